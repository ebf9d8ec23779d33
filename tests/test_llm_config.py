"""Where endpoint settings come from: options (nested and flat), environment, [tool.jarvis] in pyproject.toml,
defaults; and the errors that say where to set a missing one."""

from __future__ import annotations

from pathlib import Path

import pytest

from jarvis_pytest.errors import ConfigError
from jarvis_pytest.llm.config import find_pyproject, resolve_endpoint

PYPROJECT = """
[project]
name = "x"

[tool.jarvis.planner]
base_url = "https://file.example/v1"
model = "file-model"
api_key_env = "MY_PLANNER_KEY"
timeout = 30

[tool.jarvis]
grounder_base_url = "http://file-grounder:8000/v1"
"""


@pytest.fixture
def pyproject(tmp_path) -> Path:
    path = tmp_path / "pyproject.toml"
    path.write_text(PYPROJECT)
    return path


def test_options_beat_environment_beat_file_beat_defaults(pyproject):
    env = {"JARVIS_PLANNER_MODEL": "env-model", "JARVIS_PLANNER_API_KEY": "env-key", "MY_PLANNER_KEY": "file-key"}
    cfg = resolve_endpoint("planner", {"planner": {"base_url": "http://opt/v1", "model": None}}, env=env,
                           pyproject=pyproject, defaults={"model": "default-model"})
    assert (cfg.base_url, cfg.model, cfg.api_key, cfg.timeout) == ("http://opt/v1", "env-model", "env-key", 30.0)
    cfg = resolve_endpoint("planner", {}, env={"MY_PLANNER_KEY": "file-key"}, pyproject=pyproject)
    assert (cfg.base_url, cfg.model, cfg.api_key) == ("https://file.example/v1", "file-model", "file-key")
    flat = resolve_endpoint("planner", {"planner_model": "flat", "planner_max_retries": "7"}, env={},
                            pyproject=pyproject)
    assert flat.model == "flat" and flat.max_retries == 7


def test_flat_table_keys_and_defaults(pyproject):
    cfg = resolve_endpoint("grounder", {}, env={}, pyproject=pyproject, defaults={"model": "Hcompany/Holo2-30B-A3B"})
    assert (cfg.base_url, cfg.model, cfg.api_key) == ("http://file-grounder:8000/v1", "Hcompany/Holo2-30B-A3B", None)
    assert cfg.max_concurrency == 4


def test_missing_base_url_says_where_to_set_it():
    with pytest.raises(ConfigError) as info:
        resolve_endpoint("grounder", {}, env={}, pyproject=False, defaults={"model": "m"})
    text = str(info.value)
    assert "--grounder-base-url" in text and "JARVIS_GROUNDER_BASE_URL" in text and "[tool.jarvis.grounder]" in text


@pytest.mark.parametrize("options,match", [
    ({"planner_base_url": "ftp://x"}, "not an http"),
    ({"planner_base_url": "http://x/v1", "planner_timeout": "soon"}, "timeout must be a number"),
])
def test_bad_values(options, match):
    with pytest.raises(ConfigError, match=match):
        resolve_endpoint("planner", options, env={}, pyproject=False, defaults={"model": "m"})


def test_key_stays_out_of_public_and_repr():
    cfg = resolve_endpoint("planner", {"planner": {"base_url": "http://x/v1", "model": "m", "api_key": "sk-1"}},
                           env={}, pyproject=False)
    assert "sk-1" not in repr(cfg) and "sk-1" not in str(cfg.public())
    assert cfg.public() == {"base_url": "http://x/v1", "model": "m"}


def test_bad_toml_is_a_config_error(tmp_path):
    (tmp_path / "pyproject.toml").write_text("[tool.jarvis\n")
    with pytest.raises(ConfigError, match="pyproject.toml"):
        resolve_endpoint("planner", {}, env={}, pyproject=tmp_path / "pyproject.toml")


def test_find_pyproject_walks_up(tmp_path, pyproject):
    deep = tmp_path / "a" / "b"
    deep.mkdir(parents=True)
    assert find_pyproject(deep) == pyproject
