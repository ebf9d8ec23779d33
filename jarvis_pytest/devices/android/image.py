"""The Android emulator image: what building it needs, and its preparation (the golden snapshot).

`build()` is what `jarvis images build --only android` runs (an entry of `infra/images.py`'s `PREPARED`: never
part of a build of all images). Building (`fixtures/images/android/android.Dockerfile`, a name the Dockerfile
discovery skips) downloads what `fixtures/images/android/manifest.json` pins — the emulator and the system image
from dl.google.com, ADBKeyBoard from github.com, Markor and Etar from f-droid.org — each verified against its
SHA-256 (a pin without one stops the build first, naming the field: `apps.check_pins`); preparing boots the image
once with /dev/kvm, installs the APKs, sets the device up, dismisses the first-run screens and permission prompts
of every app the library uses, saves the emulator snapshot `golden` (with `-no-snapshot-save`: no quick-boot
snapshot besides it) and commits the container as the image the `emulator` backend runs (each task then starts
`-read-only -no-snapshot-save` from that snapshot). Before anything is downloaded, `build_blocker` says what is
missing; whether the internet can be reached is declared by the user (`JARVIS_ANDROID_DOWNLOAD=1`), never probed:
nothing here sends a packet to find out.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

from jarvis_pytest.devices.android import apps
from jarvis_pytest.errors import InfrastructureError

IMAGE_NAME = "android"
DOCKERFILE = "android.Dockerfile"
DOWNLOAD_ENV = "JARVIS_ANDROID_DOWNLOAD"
SNAPSHOT_LABEL = "org.jarvis.android.snapshot"
SNAPSHOT = "golden"
KVM = Path("/dev/kvm")
PREPARE_TIMEOUT = 1800.0
NEEDS = ("internet access to dl.google.com (the emulator and the system image "
         "system-images;android-33;google_apis;x86_64), github.com (ADBKeyBoard) and f-droid.org (Markor, Etar), "
         "and /dev/kvm for the first boot that makes the golden snapshot")
FIRST_RUN_PREFIX = "first-run: "   # the entrypoint's report of the preparation: installed, granted, tapped, checked


def kvm_problem() -> str | None:
    """Why /dev/kvm cannot be used here (None: it can)."""
    if not KVM.exists():
        return "this machine has no /dev/kvm (hardware virtualisation, or nested virtualisation in a VM)"
    if not os.access(KVM, os.R_OK | os.W_OK):
        return f"/dev/kvm is not readable and writable by this user (uid {os.getuid()}): add it to group kvm"
    return None


def build_blocker() -> str | None:
    """Why `jarvis images build --only android` cannot run on this machine (None: it can)."""
    problems = []
    kvm = kvm_problem()
    if kvm:
        problems.append(kvm)
    if os.environ.get(DOWNLOAD_ENV) != "1":
        problems.append(f"downloads are not enabled ({DOWNLOAD_ENV}=1 declares that dl.google.com, github.com and "
                        "f-droid.org are reachable; nothing is probed)")
    if not problems:
        return None
    return (f"the Android emulator image needs {NEEDS}; here: {'; '.join(problems)}. On a machine with both, run "
            f"`{DOWNLOAD_ENV}=1 jarvis images build --only android`")


def build() -> str:
    """Build the emulator image and prepare its golden snapshot; returns its tag. Stops first, with what is
    missing, where the manifest has a download it cannot verify or `build_blocker` says it cannot run."""
    manifest = apps.load_manifest()
    apps.check_pins(manifest)
    why = build_blocker()
    if why:
        raise InfrastructureError(why)
    from jarvis_pytest.infra import images
    from jarvis_pytest.infra.engine import client as docker_client

    client = docker_client(timeout=3600)
    base = images.ensure_base(client)
    tag = images.image_tag(IMAGE_NAME)
    context = images.IMAGES_DIR / IMAGE_NAME
    images._progress(f"{IMAGE_NAME}: building {tag} from {DOCKERFILE} (downloads about 1.5 GB, each verified "
                     f"against manifest.json)")
    tail: list[str] = []
    for chunk in client.api.build(path=str(context), dockerfile=DOCKERFILE, tag=tag,
                                  buildargs={"BASE": base} | apps.build_args(manifest),
                                  rm=True, forcerm=True, network_mode="host", decode=True,
                                  labels={images.NAME_LABEL: IMAGE_NAME}):
        if "error" in chunk:
            raise InfrastructureError(f"building {tag} failed: {chunk['error']}\n" + "".join(tail[-40:]))
        line = chunk.get("stream", "")
        if line:
            tail = (tail + [line])[-200:]
            if line.startswith(("Step ", "fetch: ")):
                images._progress(f"{IMAGE_NAME}: {line.strip()[:160]}")
    images._progress(f"{IMAGE_NAME}: first boot with /dev/kvm: apps, first-run screens, golden snapshot (minutes)")
    return prepare(client, tag)


def prepare(client, tag: str, timeout: float = PREPARE_TIMEOUT) -> str:
    """Boot the built image once with /dev/kvm (no network), let its entrypoint install the pinned APKs, set the
    device up, dismiss every first-run screen and save the `golden` snapshot, then commit the container over
    `tag`, saying what the first run did. Returns `tag`."""
    problem = kvm_problem()
    if problem:
        raise InfrastructureError(f"preparing the Android image needs /dev/kvm: {problem}")
    container = client.containers.run(tag, command=["prepare"], detach=True, network_mode="none",
                                      devices=["/dev/kvm:/dev/kvm:rwm"], labels={"org.jarvis.role": "image-prepare"})
    try:
        deadline = time.monotonic() + timeout
        while True:
            container.reload()
            if container.status in ("exited", "dead"):
                break
            if time.monotonic() > deadline:
                raise InfrastructureError(f"preparing {tag} took more than {timeout:.0f} s")
            time.sleep(5)
        code = container.attrs["State"].get("ExitCode")
        log = container.logs().decode("utf-8", "replace")
        if code != 0:
            tail = "\n".join(log.splitlines()[-60:])
            raise InfrastructureError(f"preparing {tag} failed (exit {code}):\n{tail}")
        from jarvis_pytest.infra import images

        for line in first_run_lines(log):
            images._progress(f"{IMAGE_NAME}: {line}")
        repo, _, version = tag.rpartition(":")
        container.commit(repository=repo, tag=version,
                         changes=[f"LABEL {SNAPSHOT_LABEL}={SNAPSHOT}", 'CMD ["run"]'])
        return tag
    finally:
        container.remove(force=True, v=True)


def first_run_lines(log: str) -> list[str]:
    """The lines of the preparation's log that say what was installed, granted, tapped and checked."""
    return [line.strip() for line in log.splitlines() if line.startswith(FIRST_RUN_PREFIX)]


def image_state(client, ref: str) -> str | None:
    """None when `ref` exists and carries the golden snapshot; else what is missing."""
    import docker.errors

    try:
        image = client.images.get(ref)
    except docker.errors.ImageNotFound:
        return f"no Android emulator image {ref}"
    if (image.labels or {}).get(SNAPSHOT_LABEL) != SNAPSHOT:
        return f"the image {ref} has no golden snapshot yet (it was built but not prepared with /dev/kvm)"
    return None
