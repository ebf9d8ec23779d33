"""File-system checks: existence, exact and partial text content, files on the transfer drive."""

from __future__ import annotations

import posixpath

from jarvis_pytest.evaluators.registry import Verdict, evaluator
from jarvis_pytest.evaluators.state import FinalState


def _short(text: str, limit: int = 120) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "…")


@evaluator("file_exists")
def file_exists(state: FinalState, path: str, platform: str | None = None) -> Verdict:
    ok = state.exists(path, platform)
    return Verdict.check(ok, f"a file at {path}", "it" if ok else "no file")


@evaluator("file_absent")
def file_absent(state: FinalState, path: str, platform: str | None = None) -> Verdict:
    ok = not state.exists(path, platform)
    return Verdict.check(ok, f"no file at {path}", "none" if ok else "a file")


@evaluator("file_text_equals")
def file_text_equals(state: FinalState, path: str, expected: str, strip: bool = True,
                     platform: str | None = None) -> Verdict:
    text = state.pull_text(path, platform)
    if text is None:
        return Verdict.check(False, f"{path} with text {_short(expected)}", "no file")
    got, want = (text.strip(), expected.strip()) if strip else (text, expected)
    return Verdict.check(got == want, f"{path} to read {_short(want)}", _short(got))


@evaluator("file_contains")
def file_contains(state: FinalState, path: str, text: str, platform: str | None = None) -> Verdict:
    content = state.pull_text(path, platform)
    if content is None:
        return Verdict.check(False, f"{path} containing {_short(text)}", "no file")
    return Verdict.check(text in content, f"{path} containing {_short(text)}", _short(content))


@evaluator("file_not_contains")
def file_not_contains(state: FinalState, path: str, text: str, platform: str | None = None) -> Verdict:
    content = state.pull_text(path, platform)
    if content is None:
        return Verdict.check(False, f"{path} without {_short(text)}", "no file")
    return Verdict.check(text not in content, f"{path} without {_short(text)}", _short(content))


@evaluator("files_identical")
def files_identical(state: FinalState, path: str, reference: str, platform: str | None = None,
                    reference_platform: str | None = None) -> Verdict:
    """`path` on this device has the same bytes as `reference` (possibly on another device)."""
    got = state.pull(path, platform)
    ref = state.pull(reference, reference_platform)
    if got is None or ref is None:
        missing = path if got is None else reference
        return Verdict.check(False, f"{path} identical to {reference}", f"no file at {missing}")
    return Verdict.check(got == ref, f"{path} identical to {reference} ({len(ref)} bytes)", f"{len(got)} different bytes" if got != ref else "identical")


@evaluator("transfer_has_file")
def transfer_has_file(state: FinalState, name: str) -> Verdict:
    """A file named `name` (basename) is somewhere on the transfer drive."""
    if state.transfer is None:
        return Verdict(False, "task has no transfer drive")
    names = sorted(posixpath.basename(p) for p in state.transfer.walk())
    base = posixpath.basename(name)
    return Verdict.check(base in names, f"{base!r} on the transfer drive", repr(names[:20]))
