"""Text read off the screen image (`agents/screen_text.py`): GUI targets the accessibility tree does not show,
such as Chromium's GTK file dialog (md-0108's transfer, a screenshot of the Ubuntu device kept in tests/data)."""

from __future__ import annotations

from pathlib import Path

import pytest

from jarvis_pytest.agents import gui_oracle
from jarvis_pytest.agents.gui_oracle import A11yView, GuiOracleAgent, await_target, brief_gui, find_screen_text
from jarvis_pytest.agents.screen_text import Word, read_words, runs
from jarvis_pytest.tasks.model import GuiTarget

SAVE_DIALOG = Path(__file__).parent / "data" / "screens" / "chromium_gtk_save_dialog.png"


def test_runs_are_the_words_of_one_line_joined_with_the_box_around_them():
    words = [Word("Save", (10, 5, 30, 10), (1, 1, 1)), Word("File", (44, 6, 25, 10), (1, 1, 1)),
             Word("Cancel", (10, 50, 40, 12), (1, 1, 2))]
    got = list(runs(words))
    assert got == [("Save", [10, 5, 30, 10]), ("Save File", [10, 5, 59, 11]), ("File", [44, 6, 25, 10]),
                   ("Cancel", [10, 50, 40, 12])]


def test_the_gtk_dialog_chromium_shows_is_found_by_its_title_on_the_screen():
    words = read_words(SAVE_DIALOG.read_bytes())
    node, window = find_screen_text(words, GuiTarget(screen_text="Save File"), (1920, 1080))
    assert window is None and node["name"] == "Save File"
    x, y, w, h = node["box"]
    assert 880 < x < 940 and 100 < y < 125 and 40 < w < 90  # the title bar, centred over the 1920 px screen
    assert find_screen_text(words, GuiTarget(screen_text="Open File*"), (1920, 1080)) == (None, None)
    second, _ = find_screen_text(words, GuiTarget(screen_text="Save", index=1), (1920, 1080))
    assert second["box"][1] > 800  # the dialog's Save button, below its title


class ScreenOnly:
    """A device that shows a fixed screen and an empty accessibility tree."""

    def __init__(self, png: bytes):
        self.png = png

    def a11y_tree(self, max_nodes=2000, timeout=5.0, showing_only=True):
        return {"tree": {"role": "desktop frame", "children": []}, "truncated": False}

    def observe(self):
        from jarvis_pytest.devices.base import Observation

        return Observation("ubuntu", self.png, 1920, 1080)


def test_a_screen_text_target_is_awaited_on_the_screen_image_and_not_in_the_tree():
    view = A11yView(ScreenOnly(SAVE_DIALOG.read_bytes()))
    found = await_target(view, GuiTarget(screen_text="save file"), 5, screen=(1920, 1080))
    assert found.node is not None and found.reads == 1
    assert await_target(view, GuiTarget(text="Save File"), 0.1).node is None  # not in the tree
    gone = await_target(view, GuiTarget(screen_text="Save File"), 0.1, gone=True)
    assert gone.node is not None  # still shows: not gone


@pytest.mark.parametrize("fields", [{"screen_text": "Save", "window": "Chromium"},
                                    {"screen_text": "Save", "text": "Save"},
                                    {"screen_text": "Save", "control": {"role": "push button"}}])
def test_screen_text_stands_alone_in_a_target(fields):
    with pytest.raises(Exception, match="screen_text"):
        GuiTarget.model_validate(fields)


def test_without_tesseract_a_plan_that_reads_the_screen_gives_up_saying_so(monkeypatch):
    from types import SimpleNamespace

    from jarvis_pytest.tasks.model import GuiStep

    step = GuiStep.model_validate({"type": "WAIT_FOR", "target": {"screen_text": "Save File"}})
    sub = SimpleNamespace(platform="ubuntu", template="t", gui_solution=[step], gui_infeasible=None, opens=None,
                          window=None)
    monkeypatch.setattr(gui_oracle, "gui_plan", lambda subs, backends, windows: (
        [gui_oracle.GuiItem(0, "ubuntu", 0, step, "gui_solution")], None))
    monkeypatch.setattr(gui_oracle.shutil, "which", lambda name: None)
    agent = GuiOracleAgent()
    brief_gui(agent, [sub], {"ubuntu": ScreenOnly(b"")}, None)
    assert "Tesseract" in agent.briefed and "apt-get install tesseract-ocr" in agent.briefed
