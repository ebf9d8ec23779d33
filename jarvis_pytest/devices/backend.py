"""Device backends: how a platform's device comes to life, found through one explicit registry.

A `Backend` is a provider in the sense of Inspect AI's sandbox providers: it owns its device's lifecycle
(`boot`, `close`; the default is one container, `infra/containers.py`), its image and how that image comes
to be (`built` here from `fixtures/images/`, `pulled` from a registry, or `prepared` once on a capable machine,
such as a Windows VM disk), its readiness check and timeout, and its memory and CPU defaults. `infra/` creates
networks and hands a backend what it needs; it knows nothing else about a platform.

A backend declares its settings (`options`: `BackendOption`s with a help text, a default, a parser or choices
and, for settings older than the option, the environment variable read when the option is not given) and is made
from their values: `backend.configure({"version": "10"})` is the same backend with those values (`values`) and the
fields that follow from them (`derive`). Users give them as `--backend-option PLATFORM.KEY=VALUE`.

`BUILTIN` maps each platform to its backends (imported on first use); `register_backend` adds more (tests,
extensions). A run resolves its backends once (`resolve_backends`): per platform the backend named
(`--windows-backend kvm`), else the first of the platform's backends that can run here, each configured from the
options; the result (`Backends`, platform → Backend, and why a platform has none) goes to everything that boots,
lists images or skips tasks. `backend_for(platform, name)` resolves one platform, outside a run. Every result
records the backend that ran (`Backend.label`) and what its device really is (`Backend.describe`, read inside the
device), what it is made from where the container's image does not say it (`Backend.provenance`, e.g. the
dockur image and memory snapshot behind a Windows VM), and stand-ins (`stand_in=True`, e.g. Windows under Wine) are
marked as such in the tables.
"""

from __future__ import annotations

import dataclasses
import importlib
import os
import threading
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Literal

from jarvis_pytest.devices.base import Device
from jarvis_pytest.errors import ConfigError, InfrastructureError

if TYPE_CHECKING:
    from jarvis_pytest.infra.containers import BootRequest, BootedDevice

CONTROL_PORT = 5000   # the control server's port inside a device container
ImageKind = Literal["built", "pulled", "prepared"]
OPTION_FLAG = "--backend-option"


@dataclass(frozen=True)
class BackendOption:
    """One setting of a backend: `--backend-option PLATFORM.KEY=VALUE`, else `$env` when it has one, else `default`.
    `parse` turns the text into the value (a ValueError saying why for a bad one, or a ConfigError with its own
    fix); `choices` limits the text."""

    key: str
    help: str
    default: Any = None
    parse: Callable[[str], Any] = str
    choices: tuple[str, ...] = ()
    env: str | None = None       # the environment variable this setting was read from before the option existed
    example: str = ""            # a good value, shown with a bad one

    def read(self, platform: str, raw: str | None) -> Any:
        """The value of the option given as `raw` (None: not given: `$env`, else the default); one ConfigError
        naming the option, the value and the fix for a bad one."""
        where = f"{OPTION_FLAG} {platform}.{self.key}"
        if raw is None and self.env:
            raw, where = os.environ.get(self.env) or None, f"${self.env}"
        if raw is None:
            return self.default
        fix = self.help + (f", e.g. {platform}.{self.key}={self.example}" if self.example else "")
        if self.choices and raw not in self.choices:
            raise ConfigError(f"{raw!r} is not one of {', '.join(self.choices)}", field=where,
                              fix=f"choose one of {', '.join(self.choices)}")
        try:
            return self.parse(raw.strip())
        except ConfigError as exc:  # a parser that says what is wrong and the fix itself
            raise ConfigError(exc.detail, field=where, fix=exc.fix or fix) from None
        except (TypeError, ValueError) as exc:
            why = f": {exc}" if str(exc) else ""
            raise ConfigError(f"{raw!r} is not valid{why}", field=where, fix=fix) from None


def backend_option_pairs(items: list[tuple[str, str]]) -> dict[str, dict[str, str]]:
    """`(flag, "PLATFORM.KEY=VALUE")` items as platform → key → text: a malformed one, or one key given two values,
    is one ConfigError naming the flag (what the keys and values may be is `check_backend_options`'s)."""
    out: dict[str, dict[str, str]] = {}
    for flag, item in items:
        name, sep, value = item.partition("=")
        platform, dot, key = name.strip().partition(".")
        if not sep or not dot or not platform or not key.strip():
            raise ConfigError(f"{item!r} is not valid", field=flag,
                              fix=f"write PLATFORM.KEY=VALUE, e.g. {OPTION_FLAG} windows.version=10")
        given = out.setdefault(platform, {})
        key = key.strip()
        if given.get(key, value) != value:
            raise ConfigError(f"{platform}.{key} is given twice ({given[key]!r} and {value!r})", field=flag,
                              fix="give it once")
        given[key] = value
    return out


def positive_int(text: str) -> int:
    """An option parser: a whole number, 1 or more."""
    value = int(text)
    if value < 1:
        raise ValueError("give 1 or more")
    return value


def token(text: str) -> str:
    """An option parser: a non-empty word without spaces (a serial, an image reference, a version)."""
    if not text or any(c.isspace() for c in text):
        raise ValueError("give one word, without spaces")
    return text


@dataclass(frozen=True)
class Backend:
    """Everything `infra/` needs to boot, connect and remove one platform's device."""

    platform: str
    image: str                                   # image name: under fixtures/images/ (built) or a reference
    connect: Callable[[str], Device]             # base URL on 127.0.0.1 → a Device
    wait_ready: Callable[[str, float], None]     # base URL, timeout s → returns when ready, raises otherwise
    name: str = "docker"                         # e.g. docker, wine, kvm, emulator, attach
    port: int = CONTROL_PORT                     # control port inside the container
    container_options: dict[str, Any] = field(default_factory=dict)  # extra docker-py `containers.run` kwargs
    image_kind: ImageKind = "built"
    ready_timeout: float = 60.0                  # seconds from create until ready
    memory: str | None = "4g"                    # default memory limit of one device
    booted_memory_mb: int = 512                  # about what one freshly booted device holds: a pre-warm starts
                                                 # only with this much free above the pool's reserve (`environments/pool.py`)
    cpus: float | None = None                    # default CPU limit of one device
    stand_in: bool = False                       # not the real platform (e.g. Windows under Wine)
    drive_mount: str | None = None               # where the device mounts the task's drive storage, if it does
    holder: bool = False                         # the default boot runs the device in a kept `PortHolder`'s
                                                 # network namespace (only for devices without NET_ADMIN)
    unavailable: Callable[[], str | None] = lambda: None  # why it cannot run on this machine (None: it can)
    how_to_run: str = ""                         # what a user does to run this backend where it cannot run yet
    describe: Callable[[Device], str] | None = None  # what the device really is, read inside it: its system's name
                                                     # and version (e.g. "Debian GNU/Linux 12 (bookworm), XFCE 4.18")
    options: tuple[BackendOption, ...] = ()      # the settings it takes (`--backend-option PLATFORM.KEY=VALUE`)
    values: Mapping[str, Any] = field(default_factory=dict)  # the value of each option it was made with
    derive: Callable[[Mapping[str, Any]], dict[str, Any]] | None = None  # option values → the fields they set
    provenance: Callable[[], dict[str, Any]] | None = None  # what its devices are made from, beyond the container's
                                                 # image, for every result (e.g. the image digest that installed a
                                                 # VM's golden, and its memory snapshot)

    def __post_init__(self) -> None:
        """Every option has its value (the default where none was given), and the fields that follow from the
        values (`derive`) are set from them."""
        if not self.options:
            return
        values = {o.key: o.default for o in self.options} | dict(self.values)
        object.__setattr__(self, "values", values)
        for name, value in (self.derive(values) if self.derive else {}).items():
            object.__setattr__(self, name, value)

    def configure(self, given: Mapping[str, str]) -> "Backend":
        """This backend made from option values as given by the user (text; absent keys: `$env`, else the
        default): itself when nothing changes. A key it does not take or a bad value is one ConfigError."""
        keys = [o.key for o in self.options]
        for key in given:
            if key not in keys:
                raise ConfigError(f"the {self.label} backend takes no option {key!r}",
                                  field=f"{OPTION_FLAG} {self.platform}.{key}", fix=_valid_keys(self.platform, keys))
        values = {o.key: o.read(self.platform, given.get(o.key)) for o in self.options}
        if values == dict(self.values):
            return self
        return dataclasses.replace(self, values=values)

    @property
    def label(self) -> str:
        """What results record: e.g. `ubuntu (docker)`, `windows (wine)`, `windows (kvm)`."""
        return f"{self.platform} ({self.name})"

    @property
    def identity(self) -> dict[str, Any]:
        """Who its devices are, the same on any host: the container's hostname and the environment that sets their
        time zone and locale (`PlatformSpec.hostname`, `timezone`, `locale`); empty for a platform without facts."""
        from jarvis_pytest.devices.platforms import PLATFORMS

        facts = PLATFORMS.get(self.platform)
        if facts is None:
            return {}
        return {"hostname": facts.hostname,
                "environment": {"TZ": facts.timezone, "LANG": facts.locale, "LC_ALL": facts.locale}}

    @property
    def image_ref(self) -> str:
        """The image reference to run: a built image's tag, or the reference as given."""
        if self.image_kind == "built":
            from jarvis_pytest.infra.images import image_tag

            return image_tag(self.image)
        return self.image

    def boot(self, request: "BootRequest") -> "BootedDevice":
        """Start the device and wait until it is ready (default: one container)."""
        from jarvis_pytest.infra.containers import boot_container

        return boot_container(self, request)

    def close(self, booted: "BootedDevice") -> list[str]:
        """Remove what `boot` made; returns what could not be removed (default: the container)."""
        from jarvis_pytest.infra.containers import remove_all

        return remove_all([booted.container])




# platform → backend name → "module:attribute", imported on first use; the first that can run is the default
BUILTIN: dict[str, dict[str, str]] = {
    "ubuntu": {"docker": "jarvis_pytest.devices.ubuntu.backend:BACKEND"},
    "windows": {"kvm": "jarvis_pytest.devices.windows.backend:KVM",
                "wine": "jarvis_pytest.devices.windows.backend:WINE"},
    "android": {"emulator": "jarvis_pytest.devices.android.backend:EMULATOR",
                "attach": "jarvis_pytest.devices.android.backend:ATTACH"},
}
ALIASES = {("windows", "real"): "kvm"}
_REGISTERED: dict[str, dict[str, Backend]] = {}


def register_backend(backend: Backend) -> None:
    """Add a backend (tests, extensions); it comes before the built-in backends of its platform."""
    _REGISTERED.setdefault(backend.platform, {})[backend.name] = backend


def _load(ref: str) -> Backend:
    module, _, attr = ref.partition(":")
    return getattr(importlib.import_module(module), attr)


def known_platforms() -> list[str]:
    """Every platform with a backend: the built-in ones in their order, then those only registered."""
    return list(dict.fromkeys([*BUILTIN, *_REGISTERED]))


def backends_of(platform: str) -> dict[str, Backend]:
    """Every backend of a platform as defined (not configured), registered ones first, then the built-in ones."""
    out = dict(_REGISTERED.get(platform, {}))
    for name, ref in BUILTIN.get(platform, {}).items():
        out.setdefault(name, _load(ref))
    return out


def option_keys(platform: str) -> dict[str, BackendOption]:
    """The options a platform's backends take, by key (the first backend's, where two take the same key)."""
    out: dict[str, BackendOption] = {}
    for backend in backends_of(platform).values():
        for option in backend.options:
            out.setdefault(option.key, option)
    return out


def _valid_keys(platform: str, keys: list[str] | None = None) -> str:
    keys = list(option_keys(platform)) if keys is None else keys
    if not keys:
        return f"the {platform} backends take no options"
    return "valid keys: " + ", ".join(f"{platform}.{k}" for k in keys)


def _all_keys() -> str:
    keys = [f"{p}.{k}" for p in known_platforms() for k in option_keys(p)]
    return f"valid keys: {', '.join(keys)}" if keys else "no backend takes options"


def _named(platform: str, name: str | None) -> str | None:
    """The backend name asked for (aliases resolved), None for auto; a ConfigError for one the platform lacks."""
    if name in (None, "", "auto"):
        return None
    name = ALIASES.get((platform, name), name)
    choices = backends_of(platform)
    if name not in choices:
        raise ConfigError(f"no {platform} backend {name!r}", field=f"--{platform}-backend",
                          fix=f"choose one of {', '.join(['auto', *choices])}")
    return name


def check_backend_options(choices: Mapping[str, str | None], given: Mapping[str, Mapping[str, str]]) -> None:
    """The backends asked for exist and every option given is one of their platform's, with a good value (of the
    backend named, when one is): one ConfigError naming the option and the valid keys otherwise. Nothing is asked
    of the machine (whether a backend can run here is `resolve_backends`'s)."""
    known = known_platforms()
    for platform, pairs in given.items():
        if platform not in known:
            key = next(iter(pairs), "KEY")
            raise ConfigError(f"no platform {platform!r}", field=f"{OPTION_FLAG} {platform}.{key}",
                              fix=f"platforms: {', '.join(known)}; {_all_keys()}")
    for platform in [p for p in known if p in choices or p in given]:
        name = _named(platform, choices.get(platform))
        pairs = dict(given.get(platform, {}))
        keys = option_keys(platform)
        for key, raw in pairs.items():
            if key not in keys:
                raise ConfigError(f"the {platform} backends take no option {key!r}",
                                  field=f"{OPTION_FLAG} {platform}.{key}", fix=_valid_keys(platform))
            keys[key].read(platform, raw)
        if name is not None:
            backend = backends_of(platform)[name]
            foreign = [k for k in pairs if k not in {o.key for o in backend.options}]
            if foreign:
                owners = [b.name for b in backends_of(platform).values() if foreign[0] in {o.key for o in b.options}]
                raise ConfigError(f"{platform}.{foreign[0]} is an option of the {' and '.join(owners)} backend, not "
                                  f"of {name}", field=f"{OPTION_FLAG} {platform}.{foreign[0]}",
                                  fix=f"drop it, or choose --{platform}-backend {owners[0]}")


def _own(backend: Backend, pairs: Mapping[str, str]) -> dict[str, str]:
    keys = {o.key for o in backend.options}
    return {k: v for k, v in pairs.items() if k in keys}


def _jsonable(value: Any) -> Any:
    return value if isinstance(value, (str, int, float, bool, type(None))) else str(value)


class Backends(Mapping[str, Backend]):
    """The run's backends, resolved once (`resolve_backends`): platform → the configured Backend that runs it;
    `why_missing(platform)` says why a platform has none on this machine. Made with `open=True` (outside a run:
    tests, `jarvis bench`), a platform not yet resolved is resolved with its defaults on first use, once."""

    def __init__(self, chosen: Mapping[str, Backend] | None = None, missing: Mapping[str, str] | None = None, *,
                 asked: Mapping[str, str | None] | None = None, given: Mapping[str, Mapping[str, str]] | None = None,
                 passed_over: Mapping[str, list[str]] | None = None, open: bool = False):
        self._chosen = dict(chosen or {})
        self._missing = dict(missing or {})
        self._asked = dict(asked or {})
        self._given = {p: dict(v) for p, v in (given or {}).items()}
        self._passed_over = {p: list(v) for p, v in (passed_over or {}).items()}  # "name: why" of backends auto
                                                                                  # tried first, that cannot run
        self._open = open
        self._lock = threading.Lock()

    def __getitem__(self, platform: str) -> Backend:
        return self._chosen[platform]

    def __iter__(self) -> Iterator[str]:
        return iter(self._chosen)

    def __len__(self) -> int:
        return len(self._chosen)

    def why_missing(self, platform: str) -> str | None:
        return self._missing.get(platform)

    def backend(self, platform: str) -> Backend:
        """The backend of `platform`; InfrastructureError when it has none on this machine (or none at all)."""
        if self._open and platform not in self._chosen and platform not in self._missing:
            with self._lock:
                if platform not in self._chosen and platform not in self._missing:
                    found = resolve_backends(only=(platform,))
                    self._chosen.update(found._chosen)
                    self._missing.update(found._missing)
        if platform in self._chosen:
            return self._chosen[platform]
        if platform in self._missing:
            raise InfrastructureError(f"no {platform} backend can run on this machine ({self._missing[platform]})")
        raise InfrastructureError(f"no device backend for platform {platform!r} (platforms with backends: "
                                  f"{sorted(known_platforms())})")

    def given(self) -> dict[str, dict[str, str]]:
        """The options given per platform (`--backend-option`, as text): with `decided`, what another process needs
        to make the same backends (`resolve_backends({}, given, decided=...)`)."""
        return {p: dict(v) for p, v in self._given.items()}

    def decided(self) -> dict[str, dict[str, str]]:
        """What was decided, as JSON (for xdist workers: `resolve_backends(decided=...)` makes the same)."""
        return {"chosen": {p: b.name for p, b in self._chosen.items()}, "missing": dict(self._missing)}

    def record(self) -> dict[str, dict[str, Any]]:
        """What the run asked for and got, per platform, for run.json: the backend asked for (auto or a name), the
        options given, the backend chosen (its label) with the value of each of its options, or why none runs,
        and why auto passed over the backends before it."""
        out: dict[str, dict[str, Any]] = {}
        for platform in dict.fromkeys([*self._chosen, *self._missing]):
            entry: dict[str, Any] = {"asked": self._asked.get(platform) or "auto",
                                     "given": dict(self._given.get(platform, {}))}
            backend = self._chosen.get(platform)
            if backend is not None:
                entry |= {"backend": backend.name, "label": backend.label,
                          "options": {k: _jsonable(v) for k, v in backend.values.items()}}
            else:
                entry |= {"backend": None, "unavailable": self._missing[platform]}
            if backend is not None and self._passed_over.get(platform):
                entry["passed_over"] = list(self._passed_over[platform])
            out[platform] = entry
        return out


def resolve_backends(choices: Mapping[str, str | None] | None = None,
                     given: Mapping[str, Mapping[str, str]] | None = None, *,
                     decided: Mapping[str, Mapping[str, str]] | None = None,
                     only: tuple[str, ...] | None = None) -> Backends:
    """The backend of every platform (or of those in `only`), once: the one named in `choices` (platform → name, None
    or "auto": the first of the platform's backends that can run here), configured from `given` (platform → key
    → text, `--backend-option`). `decided` (`Backends.decided()` of another process) replays that choice without
    asking the machine again: an xdist worker gets the backends its controller found. A bad name, key or value is
    one ConfigError (`check_backend_options`)."""
    choices = dict(choices or {})
    given = {p: dict(v) for p, v in (given or {}).items()}
    check_backend_options(choices, given)
    chosen: dict[str, Backend] = {}
    missing: dict[str, str] = {}
    passed_over: dict[str, list[str]] = {}
    for platform in only or known_platforms():
        candidates = backends_of(platform)
        if not candidates:
            continue
        pairs = given.get(platform, {})
        name = _named(platform, choices.get(platform))
        if decided is not None:
            name = decided.get("chosen", {}).get(platform)
            if name is None:
                missing[platform] = decided.get("missing", {}).get(platform) or "none chosen"
                continue
        if name is not None:
            chosen[platform] = candidates[name].configure(_own(candidates[name], pairs))
            continue
        reasons = passed_over[platform] = []
        for backend in candidates.values():
            backend = backend.configure(_own(backend, pairs))
            why = backend.unavailable()
            if why is None:
                chosen[platform] = backend
                break
            reasons.append(f"{backend.name}: {why}")
        else:
            missing[platform] = "; ".join(reasons)
    return Backends(chosen, missing, asked={p: _named(p, n) for p, n in choices.items() if p in known_platforms()},
                    given=given, passed_over=passed_over)


def backend_for(platform: str, name: str | None = None, given: Mapping[str, str] | None = None) -> Backend:
    """Outside a run (tests, device tools): the backend `name` of `platform`, or (no name) the first of its
    backends that can run here, configured from `given` (key → text), `$env` and the defaults. A run resolves
    all its backends once instead (`resolve_backends`)."""
    if platform not in known_platforms():
        raise InfrastructureError(f"no device backend for platform {platform!r} (platforms with backends: "
                                  f"{sorted(known_platforms())})")
    found = resolve_backends({platform: name}, {platform: dict(given)} if given else {}, only=(platform,))
    return found.backend(platform)


def os_release_name(text: str) -> str:
    """The system's name and version from an os-release file's text (PRETTY_NAME, else NAME VERSION)."""
    fields = {}
    for line in text.splitlines():
        key, sep, value = line.strip().partition("=")
        if sep:
            fields[key] = value.strip().strip('"').strip("'")
    return fields.get("PRETTY_NAME") or " ".join(v for v in (fields.get("NAME"), fields.get("VERSION")) if v)
