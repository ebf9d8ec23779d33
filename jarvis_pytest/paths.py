"""Where the checkout's folders are (the package runs from its repository): every module takes them from here."""

from __future__ import annotations

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
AGENTS_DIR = REPO_ROOT / "agents"          # model adapters (`agents/*.py`)
TASKS_DIR = REPO_ROOT / "tasks"            # the template library, its type system and the composed datasets
TYPES_FILE = TASKS_DIR / "types.json"
FIXTURES_DIR = REPO_ROOT / "fixtures"
FIXTURE_FILES = FIXTURES_DIR / "files"     # files set-up uploads (`upload_file` with `fixture`)
IMAGES_DIR = FIXTURES_DIR / "images"       # device image build contexts
REPORTS_DIR = REPO_ROOT / "reports"        # run folders (git-ignored)
