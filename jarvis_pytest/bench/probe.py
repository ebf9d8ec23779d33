"""Boot one desktop device container straight from its image (docker SDK) and measure it: the device's own tests
and quick measurements, independent of the task lifecycle in `infra/` (which is what runs benchmarks).

    python -m jarvis_pytest.bench.probe [--boots 5] [--samples 50]

prints what the device is (its system, read inside it), cold start (create → ready), screenshot, action and
accessibility-tree latencies (p50/p90) as JSON.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Iterator

from jarvis_pytest.devices import actions as A
from jarvis_pytest.devices.desktop import DesktopDevice

if TYPE_CHECKING:
    from jarvis_pytest.devices.backend import Backend

TEST_LABEL = "org.jarvis.test"


@dataclass
class Booted:
    """A running device container, the base URL of its control server on 127.0.0.1, and a client."""

    container: Any
    url: str
    device: DesktopDevice
    ready_s: float  # create → ready
    backend: "Backend | None" = None

    def system(self) -> str:
        """What the device is, read inside it (`Backend.describe`; "" when the backend cannot say)."""
        describe = self.backend.describe if self.backend is not None else None
        return describe(self.device) if describe else ""


@contextmanager
def boot(image: str = "jarvis/ubuntu:latest", platform: str = "ubuntu", timeout: float = 60.0,
         client: Any = None, backend: "Backend | None" = None) -> Iterator[Booted]:
    """Create a container of `image` with its control port on 127.0.0.1 (ports and options of `backend`, else the
    platform's default backend), wait until ready; always removed."""
    import docker

    from jarvis_pytest.devices.backend import backend_for
    from jarvis_pytest.errors import InfrastructureError

    backend = backend or backend_for(platform)
    client = client or docker.from_env()
    t0 = time.perf_counter()
    container = client.containers.create(image, detach=True, labels={TEST_LABEL: "1"},
                                         ports={f"{backend.port}/tcp": ("127.0.0.1", None)},
                                         **backend.container_options)
    device = None
    try:
        container.start()  # a start that fails (e.g. no default bridge) leaves nothing: `finally` removes it
        container.reload()
        url = f"http://127.0.0.1:{container.ports[f'{backend.port}/tcp'][0]['HostPort']}"
        try:
            backend.wait_ready(url, timeout)
        except InfrastructureError as exc:
            container.reload()
            logs = container.logs(tail=30).decode("utf-8", "replace")
            raise InfrastructureError(f"{exc} (container {container.status}; last log lines:\n{logs})") from None
        ready_s = time.perf_counter() - t0
        device = DesktopDevice(url, platform=platform)
        yield Booted(container, url, device, ready_s, backend)
    finally:
        if device is not None:
            device.close()
        container.remove(force=True)


def _stats(values_ms: list[float]) -> dict[str, float]:
    q = statistics.quantiles(values_ms, n=10, method="inclusive") if len(values_ms) > 1 else values_ms * 9
    return {"p50": round(statistics.median(values_ms), 1), "p90": round(q[8], 1), "n": len(values_ms)}


def _timed(fn: Callable[[], Any], n: int) -> list[float]:
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        out.append((time.perf_counter() - t0) * 1000)
    return out


def measure(image: str = "jarvis/ubuntu:latest", boots: int = 5, samples: int = 50) -> dict:
    """Cold starts of `boots` fresh containers; latencies over `samples` calls on the last one."""
    cold: list[float] = []
    for i in range(boots):
        with boot(image) as b:
            cold.append(b.ready_s * 1000)
            if i < boots - 1:
                continue
            d = b.device
            d.screenshot()
            result = {
                "image": image,
                "device_os": b.system(),
                "cold_start_ms": _stats(cold),
                "screenshot_ms": _stats(_timed(d.screenshot, samples)),
                "move_to_ms": _stats(_timed(lambda: d.act(A.MoveTo(x=700, y=500)), samples)),
                "click_ms": _stats(_timed(lambda: d.act(A.Click(x=960, y=600)), samples)),
                "hotkey_ms": _stats(_timed(lambda: d.act(A.Hotkey(keys=["shift"])), samples)),
                "typing_10_chars_ms": _stats(_timed(lambda: d.act(A.Typing(text="jarvis <{}")), samples)),
                "a11y_tree_ms": _stats(_timed(d.a11y_tree, max(5, samples // 5))),
                "observe_with_a11y_ms": _stats(_timed(lambda: d.observe(a11y=True), max(5, samples // 5))),
                "screenshot_bytes": len(d.screenshot()),
            }
    return result


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m jarvis_pytest.bench.probe", description=__doc__.split("\n")[0])
    p.add_argument("--image", default="jarvis/ubuntu:latest")
    p.add_argument("--boots", type=int, default=5)
    p.add_argument("--samples", type=int, default=50)
    args = p.parse_args(argv)
    print(json.dumps(measure(args.image, args.boots, args.samples), indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
