"""The perception CLI's help and errors, and layered configuration."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from pydantic import BaseModel, ConfigDict, Field

from common.runtime.config import ConfigError, load_config
from common.messages.keys import Keys
from perception.cli import COMMANDS, main

PY = sys.executable


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_command_has_help(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main([command, "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert f"usage: perception {command}" in out and len(out) > 200


def test_top_level_help_lists_commands(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    for command in COMMANDS:
        assert command in out


def test_bad_endpoint_is_a_clear_cli_error() -> None:
    res = subprocess.run([PY, "-m", "perception", "status", "--connect", "localhost:7447"], capture_output=True, text=True, timeout=60)
    assert res.returncode == 2
    assert "is not of the form PROTO/ADDRESS" in res.stderr and "Traceback" not in res.stderr


def test_bad_robot_name_is_a_clear_cli_error() -> None:
    res = subprocess.run([PY, "-m", "perception", "keys", "--robot", "a/b"], capture_output=True, text=True, timeout=60)
    assert res.returncode == 2 and "robot name 'a/b'" in res.stderr


def test_keys_are_versioned_and_the_table_lists_every_stream() -> None:
    keys = Keys(robot="mbot")
    assert keys.frames("head") == "pp/mbot/perception/v1/frames/head"
    assert keys.alive("tracker", "x") == "pp/mbot/perception/v1/alive/tracker/x"
    assert keys.stream_of(keys.embeddings("head")) == "embeddings"
    table = keys.markdown_table()
    for stream in ("frames/{camera}", "tracks", "tf_static", "query/track"):
        assert f"`{stream}`" in table
    with pytest.raises(ValueError):
        keys.frames("a/b")


class _Gate(BaseModel):
    model_config = ConfigDict(extra="forbid")
    s_max: float = Field(default=0.05, gt=0)


class _Cfg(BaseModel):
    model_config = ConfigDict(extra="forbid")
    camera: str = "head"
    max_age: int = Field(default=5, ge=1, le=100)
    gate: _Gate = _Gate()


def test_config_layers_defaults_file_env_flags(tmp_path: Path) -> None:
    f = tmp_path / "c.yaml"
    f.write_text("tracker:\n  camera: front\n  max_age: 7\n  gate: {s_max: 0.1}\n")
    env = {"PERCEPTION_TRACKER__MAX_AGE": "9", "PERCEPTION_TRACKER__GATE__S_MAX": "0.2", "OTHER": "x"}
    cfg = load_config(_Cfg, f, env_prefix="PERCEPTION_TRACKER", section="tracker", environ=env, overrides={"camera": None})
    assert (cfg.camera, cfg.max_age, cfg.gate.s_max) == ("front", 9, 0.2)
    cfg = load_config(_Cfg, f, env_prefix="PERCEPTION_TRACKER", section="tracker", environ=env, overrides={"max_age": 3})
    assert cfg.max_age == 3
    assert load_config(_Cfg) == _Cfg()


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("max_age: 0\n", "max_age: Input should be greater than or equal to 1 (got 0)"),
        ("gate: {s_max: -1}\n", "gate.s_max: Input should be greater than 0"),
        ("maxage: 3\n", "maxage: Extra inputs are not permitted"),
        ("- 1\n- 2\n", "must hold a mapping"),
        ("a: [1\n", "cannot be parsed"),
    ],
)
def test_bad_config_names_the_problem(tmp_path: Path, text: str, message: str) -> None:
    f = tmp_path / "c.yaml"
    f.write_text(text)
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")):
        load_config(_Cfg, f)


def test_missing_config_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="does not exist"):
        load_config(_Cfg, tmp_path / "nope.yaml")
