"""Infrastructure: the Docker engine, device images, containers, networks, the pre-warm pool, cleanup.

Modules: `engine` (make a Docker engine answer), `images` (build device images), `containers` (one labelled,
loopback-only container and its readiness; the holders whose network namespace devices run in), `lifecycle` (a
task's network, devices and transfer drive), `pool` (pre-warming), `cleanup` (leftovers of crashed runs),
`transfer` (host-side drive clients), `transfer_server` (which server runs the drive), `bench` (`jarvis bench
devices`), `commands` (the CLI), `lazy_modules` (what the Docker SDK imports that is rarely used).
"""

from jarvis_pytest.infra import lazy_modules

lazy_modules.install()  # before any module of this package imports docker
