"""What the Command Prompt alone does: a batch file that makes folders where it runs, run again by the evaluator
in a scratch folder. Everything else a Windows file task leaves — a file copied, moved, sorted or trashed, a
folder's content, a listing, a number written to a file — is judged by the platform-neutral evaluators
(`folders.py`, `text.py`) from `file_facts` (on Windows the probe, `windows_probe.py`), every entry counting,
hidden and system ones included.
"""

from __future__ import annotations

import uuid

from jarvis_pytest.evaluators.file_facts import NOTHING, read_facts
from jarvis_pytest.evaluators.folders import check_file, check_tree, found_part, platform_of
from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState
from jarvis_pytest.evaluators.windows_probe import PROBE_DIR


# -- Command Prompt ----------------------------------------------------------------------------------------------
@evaluator("windows_batch_creates")
def windows_batch_creates(state: FinalState, bat: str, folder: str, names: list[str],
                          platform: str | None = None) -> Verdict:
    """The batch file `bat` creates the sub-folders `names` in the current directory, and was run in `folder`:
    `folder` holds them; then `bat` is run once more by the evaluator in an empty scratch folder (its input from
    NUL, so a `pause` does not wait) and must create exactly those folders there, and nothing else, hidden or not
    — a batch file that does nothing, writes elsewhere, or makes only some of them fails."""
    plat = platform_of(state, platform)
    want = f"{bat} creating {names} where it runs, run in {folder}"
    facts = read_facts(state, entries=[bat], trees=[folder], depth=1, platform=plat.name)
    why = check_file(plat, facts.entries[bat], None, "batch file")
    if why:
        return Verdict.check(False, want, why)
    found = {plat.normalise(rel): entry for rel, entry in (facts.trees[folder] or {}).items()}
    missing = [n for n in names if found.get(plat.normalise(n), NOTHING).kind != "dir"]
    if missing:
        return Verdict.check(False, want, f"no folder {missing} in {folder} (the batch file not run there?)")
    scratch = f"{PROBE_DIR}\\run-{uuid.uuid4().hex[:12]}"
    device = state.device(plat.name)
    try:
        res = device.run(f'mkdir "{scratch}" && cd /d "{scratch}" && call "{bat}" <nul', timeout=60)
        made = read_facts(state, trees=[scratch], platform=plat.name).trees[scratch] or {}
    finally:
        device.run(f'rmdir /s /q "{scratch}"', timeout=60)
    verdict = check_tree(plat, "a scratch folder", made, list(names), {}, [], exact=True)
    if not verdict.passed:
        timed_out = " (it ran past 60 s)" if res.returncode == 124 else ""
        return Verdict(False, f"run in an empty folder{timed_out}, the batch file left: "
                       + found_part(verdict) + f"; expected {names} as folders there")
    return Verdict.check(True, want, f"it creates {names} where it runs, and they are in {folder}")
