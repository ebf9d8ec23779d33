"""The built-in file-transfer task (paper §4.2), inserted on every edge whose ends are on different platforms.

Its platform is the destination. Input ``transferred_file`` (type ``file``: any file) is the upstream output on
the source platform; output ``received_file`` is the same file, under the same name, in the destination's
transfer folder (`PlatformSpec.transfer_folder`), with the upstream file's own type. The agent moves it through
the network drive (address and credentials are given to the agent separately). Evaluators: the drive saw the file,
and the file on the destination is byte for byte the source's, as is the drive's copy (one SHA-256). The oracle solution uploads on the source and downloads on the
destination with each device's own means (`PlatformSpec.drive_put_command`/`drive_get_command`: curl on Linux,
a copy to the drive letter `S:` on Windows, where Wine has no curl.exe), against the copyparty flavour.
"""

from __future__ import annotations

from functools import lru_cache

from jarvis_pytest.devices.platforms import spec
from jarvis_pytest.infra.transfer_server import TRANSFER_ALIAS, TRANSFER_FOLDER, TRANSFER_PASSWORD, TRANSFER_PORT
from jarvis_pytest.tasks.model import (Command, EvaluatorSpec, InputSlot, OutputSlot, SolutionStep,
                                       TaskTemplate)
from jarvis_pytest.tasks.types import FILE_TYPE

TRANSFER_INPUT = "transferred_file"
TRANSFER_OUTPUT = "received_file"
_URL = f"http://{TRANSFER_ALIAS}:{TRANSFER_PORT}{TRANSFER_FOLDER}/{{{{{TRANSFER_INPUT}.name}}}}"


def _mkdir(platform: str) -> Command:
    facts = spec(platform)
    return Command(command=facts.mkdir_command(facts.transfer_folder), user=facts.desktop_user)


@lru_cache(maxsize=None)
def transfer_template(source: str, dest: str) -> TaskTemplate:
    """The transfer task from platform `source` to platform `dest` (id `transfer-<source>-to-<dest>`)."""
    if source == dest:
        raise ValueError("a transfer task needs two different platforms")
    src, dst = spec(source).device_name, spec(dest).device_name
    upload = spec(source).drive_put_command(f"{{{{{TRANSFER_INPUT}}}}}", _URL, TRANSFER_PASSWORD)
    download = spec(dest).drive_get_command(_URL, f"{{{{{TRANSFER_OUTPUT}}}}}", TRANSFER_PASSWORD)
    return TaskTemplate(
        id=f"transfer-{source}-to-{dest}",
        platform=dest,
        app="transfer",
        instruction=(f"Transfer {{{{{TRANSFER_INPUT}}}}} from the {src} to the {dst} through the network drive, "
                     f"and save it on the {dst} as {{{{{TRANSFER_OUTPUT}}}}}."),
        inputs={TRANSFER_INPUT: InputSlot(type=FILE_TYPE, description="the file on the source platform")},
        outputs={TRANSFER_OUTPUT: OutputSlot(
            type=FILE_TYPE, value=spec(dest).transfer_folder + spec(dest).sep + f"{{{{{TRANSFER_INPUT}.name}}}}",
            same_type_as=TRANSFER_INPUT, content_checked=False,
            description="the same file in the destination's transfer folder")},
        config=[_mkdir(dest)],
        evaluate=[EvaluatorSpec(func="transfer_has_file", args={"name": f"{{{{{TRANSFER_INPUT}.name}}}}"}),
                  EvaluatorSpec(func="transfer_arrived_unchanged", args={
                      "source": f"{{{{{TRANSFER_INPUT}}}}}", "source_platform": source,
                      "path": f"{{{{{TRANSFER_OUTPUT}}}}}", "folder": TRANSFER_FOLDER})],
        solution=[SolutionStep(command=upload, platform=source, user=spec(source).desktop_user,
                               note="upload to the network drive"),
                  SolutionStep(command=download, user=spec(dest).desktop_user, note="download from the network drive")],
        source_platform=source,
        description=f"Built-in: move a file from the {src} to the {dst} through the network drive.",
    )


def is_transfer(template_id: str) -> bool:
    """Whether a template id names a built-in transfer task."""
    return template_id.startswith("transfer-") and "-to-" in template_id
