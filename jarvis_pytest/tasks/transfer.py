"""The built-in file-transfer task (paper §4.2), inserted on every edge whose ends are on different platforms.

Its platform is the destination. Input ``transferred_file`` (type ``file``: any file) is the upstream output on
the source platform; output ``received_file`` is the same file, under the same name, in the destination's
transfer folder (`PlatformSpec.transfer_folder`), with the upstream file's own type. The agent moves it through
the network drive (address and credentials are given to the agent separately).

Its evaluator proves the transfer by provenance, not by a name (`evaluators/transfer.py`): the drive's ledger says
which versions of the file the drive received during the agent's turn and which of them someone took off the
drive; the file on the destination must be one of those served versions, and it must hold the source's bytes.
Which side is compared is decided by the graph's order (`transfer_links`): a side that a later subtask changes on
purpose is not compared, and that subtask's evaluators take the arrived bytes as their baseline instead.

The oracle solution uploads on the source and downloads on the destination with each device's own means
(`PlatformSpec.drive_put_command`/`drive_get_command`: curl on Linux, a copy to the drive letter `S:` on Windows,
where Wine has no curl.exe), against the copyparty flavour. Its GUI solution types the same commands into a
command line each device opens through its GUI (XFCE's terminal shortcut; Wine's Start > Run... > cmd.exe), as an
agent told the drive's address would; a browser on the drive's web page would be another way.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Sequence

from jarvis_pytest.devices.platforms import spec
from jarvis_pytest.infra.transfer_server import TRANSFER_ALIAS, TRANSFER_FOLDER, TRANSFER_PASSWORD, TRANSFER_PORT
from jarvis_pytest.tasks.model import (Command, Edge, EvaluatorSpec, GuiStep, InputSlot, OutputSlot, SolutionStep,
                                       Subtask, TaskTemplate)
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
        evaluate=[EvaluatorSpec(func="transfer_arrived_unchanged", args={
                      "source": f"{{{{{TRANSFER_INPUT}}}}}", "source_platform": source,
                      "path": f"{{{{{TRANSFER_OUTPUT}}}}}", "folder": TRANSFER_FOLDER})],
        solution=[SolutionStep(command=upload, platform=source, user=spec(source).desktop_user,
                               note="upload to the network drive"),
                  SolutionStep(command=download, user=spec(dest).desktop_user, note="download from the network drive")],
        gui_solution=_gui_solution(source, dest, upload, download),
        source_platform=source,
        description=f"Built-in: move a file from the {src} to the {dst} through the network drive.",
    )


def _gui_solution(source: str, dest: str, upload: str, download: str) -> list[GuiStep]:
    """The same commands typed into each device's command line opened through the GUI (`PlatformSpec.
    gui_shell_steps`), an agent's own way; none where a platform has no such recipe (Android)."""
    up = spec(source).gui_shell_steps(upload, "upload to the network drive")
    down = spec(dest).gui_shell_steps(download, "download from the network drive")
    if not up or not down:
        return []
    return [GuiStep.model_validate(step) for step in up + down]


def is_transfer(template_id: str) -> bool:
    """Whether a template id names a built-in transfer task."""
    return template_id.startswith("transfer-") and "-to-" in template_id


@dataclass(frozen=True)
class TransferLinks:
    """Where a transfer subtask sits in its task's graph, decided by the graph's order (subtasks are in execution
    order): what it carries, and which side of it a later subtask changes on purpose (its `consumes`)."""

    upstream: int | None = None              # the subtask whose output it carries
    downstream: tuple[int, ...] = ()         # the subtasks its received file feeds
    source_changed_later: bool = False       # a subtask after it moves, deletes or edits the source file
    destination_consumed: str | None = None  # how a subtask after it consumes the received file: edit, move, delete
    upstream_edits_in_place: bool = False    # the upstream edits the carried file where set-up made it: the file's
                                             # set-up content is the upstream's input, never its output


def _consumption(sub: Subtask, platform: str, path: str) -> str | None:
    """How `sub` consumes the file at `path` on `platform` (its `consumes` of an input bound to that path)."""
    if sub.platform != platform:
        return None
    facts = spec(platform)
    for name, how in sorted(sub.consumes.items()):
        slot = sub.input.get(name)
        if slot is not None and facts.normalise(str(slot.value)) == facts.normalise(path):
            return how
    return None


def transfer_links(subtasks: Sequence[Subtask], edges: Sequence[Edge], t: int) -> TransferLinks:
    """The links of transfer subtask `t`. Only a subtask that runs after the transfer can change a side of it: the
    subtask that made or edited the file before it was carried changes nothing "later"."""
    sub = subtasks[t]
    source, received = str(sub.input[TRANSFER_INPUT].value), str(sub.output[TRANSFER_OUTPUT].value)
    upstream = next((e.from_[0] for e in edges if e.to[0] == t), None)
    downstream = tuple(sorted({e.to[0] for e in edges if e.from_[0] == t}))
    later = subtasks[t + 1:]
    source_changed = any(_consumption(s, sub.source_platform or "", source) for s in later)
    consumed = next((how for s in later if (how := _consumption(s, sub.platform, received))), None)
    in_place = upstream is not None and _consumption(subtasks[upstream], sub.source_platform or "", source) == "edit"
    return TransferLinks(upstream=upstream, downstream=downstream, source_changed_later=source_changed,
                         destination_consumed=consumed, upstream_edits_in_place=in_place)
