"""The built-in file-transfer task (paper §4.2), inserted on every edge whose ends are on different platforms.

Its platform is the destination. Input ``transferred_file`` (type ``file``: any file) is the upstream output on
the source platform; output ``received_file`` is the same file, under the same name, in the destination's
transfer folder (:data:`TRANSFER_DIRS`), with the upstream file's own type. The agent moves it through the
network drive (address and credentials are given to the agent separately). Evaluators: the file exists on the
destination, and passed through the drive. The oracle solution uploads with curl on the source and downloads on
the destination (copyparty flavour of the drive; the device needs `curl`).
"""

from __future__ import annotations

from functools import lru_cache

from jarvis_pytest.devices.backend import (DESKTOP_USER, TRANSFER_ALIAS, TRANSFER_FOLDER, TRANSFER_PASSWORD,
                                           TRANSFER_PORT)
from jarvis_pytest.tasks.instruction import PLATFORM_NAMES
from jarvis_pytest.tasks.model import (Command, EvaluatorSpec, InputSlot, OutputSlot, SolutionStep,
                                       TaskTemplate)
from jarvis_pytest.tasks.types import FILE_TYPE

TRANSFER_DIRS = {
    "ubuntu": "/tmp/transfer",
    "android": "/sdcard/Download/transfer",
    "windows": "C:\\Users\\Docker\\Downloads\\transfer",
}
TRANSFER_INPUT = "transferred_file"
TRANSFER_OUTPUT = "received_file"
_URL = f"http://{TRANSFER_ALIAS}:{TRANSFER_PORT}{TRANSFER_FOLDER}/{{{{{TRANSFER_INPUT}.name}}}}"


def _sep(platform: str) -> str:
    return "\\" if platform == "windows" else "/"


def _mkdir(platform: str) -> Command:
    folder = TRANSFER_DIRS[platform]
    if platform == "windows":
        return Command(command=f'mkdir "{folder}"', allow_fail=True)
    return Command(command=f"mkdir -p '{folder}'", user=DESKTOP_USER if platform == "ubuntu" else None)


def _curl(platform: str, args: str) -> str:
    if platform == "windows":
        return f'curl.exe -fsS -H "PW: {TRANSFER_PASSWORD}" {args.replace(chr(39), chr(34))}'
    return f"curl -fsS -H 'PW: {TRANSFER_PASSWORD}' {args}"


@lru_cache(maxsize=None)
def transfer_template(source: str, dest: str) -> TaskTemplate:
    """The transfer task from platform `source` to platform `dest` (id `transfer-<source>-to-<dest>`)."""
    if source == dest:
        raise ValueError("a transfer task needs two different platforms")
    src, dst = PLATFORM_NAMES[source], PLATFORM_NAMES[dest]
    upload = _curl(source, f"-T '{{{{{TRANSFER_INPUT}}}}}' '{_URL}'")
    download = _curl(dest, f"-o '{{{{{TRANSFER_OUTPUT}}}}}' '{_URL}'")
    return TaskTemplate(
        id=f"transfer-{source}-to-{dest}",
        platform=dest,
        app="transfer",
        instruction=(f"Transfer {{{{{TRANSFER_INPUT}}}}} from the {src} to the {dst} through the network drive, "
                     f"and save it on the {dst} as {{{{{TRANSFER_OUTPUT}}}}}."),
        inputs={TRANSFER_INPUT: InputSlot(type=FILE_TYPE, description="the file on the source platform")},
        outputs={TRANSFER_OUTPUT: OutputSlot(
            type=FILE_TYPE, value=TRANSFER_DIRS[dest] + _sep(dest) + f"{{{{{TRANSFER_INPUT}.name}}}}",
            same_type_as=TRANSFER_INPUT, content_checked=False,
            description="the same file in the destination's transfer folder")},
        config=[_mkdir(dest)],
        evaluate=[EvaluatorSpec(func="file_exists", args={"path": f"{{{{{TRANSFER_OUTPUT}}}}}"}),
                  EvaluatorSpec(func="transfer_has_file", args={"name": f"{{{{{TRANSFER_INPUT}.name}}}}"})],
        solution=[SolutionStep(command=upload, platform=source, note="upload to the network drive"),
                  SolutionStep(command=download, note="download from the network drive")],
        source_platform=source,
        description=f"Built-in: move a file from the {src} to the {dst} through the network drive.",
    )


def is_transfer(template_id: str) -> bool:
    """Whether a template id names a built-in transfer task."""
    return template_id.startswith("transfer-") and "-to-" in template_id
