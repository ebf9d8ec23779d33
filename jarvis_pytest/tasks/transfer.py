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
where Wine has no curl.exe), against the copyparty flavour. Its GUI solution goes through the drive's web page in
the device's browser where it has one (Ubuntu: Chromium, an upload form and "Save link as…"), and elsewhere types the
oracle's command into a command line the device opens through its GUI (Wine: Start > Run... > cmd.exe; Wine has no
browser, and its Explorer's Copy and Paste did nothing when tried), as an agent told the drive's address would.
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
    """Each side through its GUI: the drive's web page in the device's browser where it has one (`_browser_upload`,
    `_browser_download`), else the oracle's command typed into the command line the device opens through its GUI
    (`PlatformSpec.gui_shell_steps`); none where a platform has neither (Android)."""
    up = _browser_upload(source) or spec(source).gui_shell_steps(upload, "upload to the network drive")
    down = _browser_download(dest) or spec(dest).gui_shell_steps(download, "download from the network drive")
    if not up or not down:
        return []
    return [GuiStep.model_validate(step) for step in up + down]


def _open_drive_page(facts, note: str) -> list[dict]:
    """The drive's folder in the device's browser, started from its command line: copyparty's basic view (`?b=u`),
    a plain upload form above the folder's listing, whose links carry the password given in the address."""
    page = f"http://{TRANSFER_ALIAS}:{TRANSFER_PORT}{TRANSFER_FOLDER}/?b=u&pw={TRANSFER_PASSWORD}"
    return facts.gui_shell_steps(facts.start_command(facts.browser, [page]), note)


def _step(platform: str, kind: str, **fields) -> dict:
    return {"type": kind, "platform": platform, **fields}


def _browser_upload(platform: str) -> list[dict]:
    """Upload through the drive's web page: "Choose Files", the file's path typed into the file dialog, "start
    upload", and the drive's answer awaited (its page links back to the folder only once the upload is stored)."""
    facts = spec(platform)
    dialog = facts.file_dialog
    if facts.browser is None or dialog is None:
        return []
    choose = {"control": {"role": "push button", "name": "Choose Files*"}}
    return [*_open_drive_page(facts, "open the drive's web page"),
            _step(platform, "WAIT_FOR", target=choose, timeout=60, note="the page with its upload form"),
            _step(platform, "CLICK", target=choose),
            _step(platform, "WAIT_FOR", target={"screen_text": dialog.open_title}, timeout=dialog.shows_within,
                  note="the file dialog, by its title on the screen (it is in no accessibility tree)"),
            _step(platform, "HOTKEY", keys=list(dialog.type_path)),
            _step(platform, "TYPING", text=f"{{{{{TRANSFER_INPUT}}}}}"),
            _step(platform, "HOTKEY", keys=list(dialog.open)),
            _step(platform, "WAIT_FOR", timeout=20, note="the form holds the file",
                  target={"control": {"role": "push button", "name": f"Choose Files: {{{{{TRANSFER_INPUT}.name}}}}"}}),
            _step(platform, "CLICK", target={"control": {"role": "push button", "name": "start upload"}},
                  note="upload to the network drive"),
            _step(platform, "WAIT_FOR", target={"control": {"role": "link", "name": "return to*"}}, timeout=60,
                  note="the drive's answer: the file is stored")]


def _browser_download(platform: str) -> list[dict]:
    """Download through the drive's web page: the file's link, "Save link as…" in its context menu, and the whole
    destination path typed as the name in the file dialog."""
    facts = spec(platform)
    dialog = facts.file_dialog
    if facts.browser is None or dialog is None:
        return []
    link = {"control": {"role": "link", "name": f"{{{{{TRANSFER_INPUT}.name}}}}"}}
    save_as = {"control": {"role": "menu item", "name": "Save link as*"}}
    return [*_open_drive_page(facts, "open the drive's web page"),
            _step(platform, "WAIT_FOR", target=link, timeout=60, note="the file's link in the drive's folder"),
            _step(platform, "RIGHT_CLICK", target=link),
            _step(platform, "CLICK", target=save_as),
            _step(platform, "WAIT_FOR", target={"screen_text": dialog.save_title}, timeout=dialog.shows_within,
                  note="the file dialog, by its title on the screen (it is in no accessibility tree)"),
            _step(platform, "HOTKEY", keys=["ctrl", "a"], note="the suggested name, replaced by the whole path"),
            _step(platform, "TYPING", text=f"{{{{{TRANSFER_OUTPUT}}}}}"),
            _step(platform, "HOTKEY", keys=list(dialog.save), note="download from the network drive"),
            _step(platform, "WAIT_FOR", target={"screen_text": dialog.save_title}, gone=True,
                  timeout=dialog.shows_within, note="the dialog closed: Chromium saves the file"),
            _step(platform, "WAIT", seconds=3, note="the download is written")]


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
