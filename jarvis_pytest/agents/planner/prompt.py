"""The planner's prompt: the template ``prompt.txt`` beside this module, with ``{{TRANSFER}}`` (the transfer
server's address and credentials), ``{{CURRENT_HISTORY}}`` (the paper's history summary, "Step N on <platform>:
<plan>", with the framework's errors) and ``{{USER_QUERY}}`` (the instruction) filled in."""

from __future__ import annotations

import re
from pathlib import Path

from jarvis_pytest.agents.planner.tools import one_line
from jarvis_pytest.agents.protocol import HistoryEntry, TaskContext

PROMPT_FILE = Path(__file__).with_name("prompt.txt")

_TRANSFER = """You have access to {a_server}.
- url: {{url}}
- username: {{user}}
- password: {{password}}
- folder: {{folder}}

You can upload files to {the_server} or download files from {the_server} by browser on all platforms.
- first, open this url in browser: {{url}}
{steps}"""

# Per server flavour, a template for url, user, password and folder; "alist" is the paper's text word for word.
TRANSFER_TEXT = {
    "alist": _TRANSFER.format(a_server="a alist server", the_server="the alist server", steps="""\
- then, login with username: {user} and password: {password}
- select the folder {folder}
- select file to download, or click bottom-right "three dot button" to find the upload file button to upload file."""),
    "copyparty": _TRANSFER.format(a_server="a file server (copyparty)", the_server="the file server", steps="""\
- then, log in with password: {password} (the login box asks only for the password)
- open the folder {folder}
- click a file to download it, or use the upload panel at the top of the folder page to upload a file."""),
}


def render_history(history: list[HistoryEntry]) -> str:
    """The paper's history summary, one line per step, with the framework's error after it."""
    if not history:
        return "(none)"
    lines = []
    for n, entry in enumerate(history, 1):
        line = f"Step {n} on {entry.platform or 'no platform'}: {one_line(entry.plan) or '(no plan)'}"
        if entry.error:
            line += f" -- ERROR: {one_line(entry.error)}"
        lines.append(line)
    return "\n".join(lines)


def render_transfer(transfer: dict[str, str]) -> str:
    """Section 7 of the prompt: the transfer server's address and credentials (the paper's AList text unless the
    harness says ``flavour: copyparty``)."""
    if not transfer.get("url"):
        return "No file transfer server is available for this task."
    flavour = transfer.get("flavour") or transfer.get("kind") or "alist"
    template = TRANSFER_TEXT.get(str(flavour).lower(), TRANSFER_TEXT["alist"])
    return template.format(url=transfer["url"], user=transfer.get("user", "agent"),
                           password=transfer.get("password", ""), folder=transfer.get("folder", "/data"))


def render_prompt(task: TaskContext, history: list[HistoryEntry], template: str | None = None) -> str:
    """The planner prompt with {{TRANSFER}}, {{CURRENT_HISTORY}} and {{USER_QUERY}} filled in."""
    text = PROMPT_FILE.read_text(encoding="utf-8") if template is None else template
    values = {"TRANSFER": render_transfer(dict(task.transfer)), "CURRENT_HISTORY": render_history(history),
              "USER_QUERY": task.instruction}
    return re.sub(r"\{\{(TRANSFER|CURRENT_HISTORY|USER_QUERY)\}\}", lambda m: values[m.group(1)], text)
