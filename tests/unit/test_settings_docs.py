"""Settings declared once: the generated rows and tables, and every README's marked table held to the code."""

from __future__ import annotations

import argparse
import re
from pathlib import Path
from typing import Literal

import pytest
from pydantic import BaseModel, ConfigDict, ValidationError

from common.runtime.settings import AdvancedBlock, flag_help, markdown_table, setting, setting_rows, settings_epilog
from tools.system import settings_docs


class Inner(BaseModel):
    model_config = ConfigDict(extra="forbid")

    radius_m: float = setting(0.5, "how far a point may be", unit="m", gt=0.0, le=2.0)
    stride: int = setting(8, "window step", unit="px", ge=8, le=64, multiple_of=8, advanced=True)


class Limits(BaseModel):
    low: float = setting(..., "lowest value", ge=0.0)


class Small(BaseModel):
    model_config = ConfigDict(extra="forbid")

    name: str = setting("head", "camera name", min_length=1)
    mode: Literal["fast", "exact"] = setting("fast", "how to search")
    rate_hz: float | None = setting(None, "most frames per second; none: every frame", unit="Hz", gt=0.0)
    size: tuple[int, int] = setting((128, 64), "input (H, W)", unit="px")
    model: Path | None = setting(None, "the model file")
    names: list[str] = setting(description="the names", default_factory=lambda: ["a", "b"])
    limits: Limits | None = setting(None, "optional bounds")
    inner: Inner = setting(description="the search's section", default_factory=Inner)


def _rows() -> dict[str, object]:
    return {r.name: r for r in setting_rows(Small)}


def test_rows_walk_nested_sections_with_ranges_units_and_defaults() -> None:
    rows = _rows()
    assert list(rows) == ["name", "mode", "rate_hz", "size", "model", "names", "limits", "limits.low",
                          "inner.radius_m", "inner.stride"]
    r = rows["inner.radius_m"]
    assert (r.default, r.range, r.unit, r.description, r.advanced) == ("0.5", "(0, 2]", "m",
                                                                       "how far a point may be", False)
    assert rows["inner.stride"].range == "[8, 64], multiple of 8" and rows["inner.stride"].advanced
    assert rows["mode"].range == "fast, exact"
    assert (rows["rate_hz"].default, rows["rate_hz"].range, rows["rate_hz"].unit) == ("none", "> 0 or none", "Hz")
    assert rows["size"].default == "[128, 64]" and rows["size"].type == "(integer, integer)"
    assert rows["model"].type == "path or none"
    assert rows["names"].default == "[a, b]"
    assert rows["name"].range == "not empty"
    assert rows["limits"].type == "{low} or none" and rows["limits.low"].default == "required"


def test_setting_keeps_pydantic_validation_and_needs_a_description() -> None:
    with pytest.raises(ValidationError, match="less than or equal to 2"):
        Small(inner={"radius_m": 3.0})
    with pytest.raises(ValidationError, match="multiple of 8"):
        Inner(stride=12)
    assert Small().inner.stride == 8
    with pytest.raises(TypeError, match="needs a description"):
        setting(1.0, "")


def test_markdown_table_puts_advanced_settings_in_a_second_table() -> None:
    text = markdown_table(Small)
    main, advanced = text.split("Advanced (tuning")
    assert "| `inner.radius_m` | `0.5` | (0, 2] | m | how far a point may be |" in main
    assert "inner.stride" not in main and "| `inner.stride` | `8` | [8, 64], multiple of 8 | px |" in advanced
    only = markdown_table(Small, "inner")
    assert "inner.radius_m" in only and "`name`" not in only
    with pytest.raises(ValueError, match="no section 'nope'; its sections: limits, inner"):
        markdown_table(Small, "nope")


def test_help_text_comes_from_the_declaration() -> None:
    epilog = settings_epilog(Small, "small")
    assert "PERCEPTION_SMALL__" in epilog and "  inner.radius_m = 0.5 m; (0, 2]" in epilog
    assert max(len(line) for line in epilog.splitlines()) <= 79
    assert flag_help(Small, "rate_hz", "process at most HZ frames per second") == (
        "process at most HZ frames per second (setting rate_hz: default none; > 0 or none)")
    parser = argparse.ArgumentParser()
    parser.add_argument("--share", help=flag_help(Small, "inner.radius_m", "100% of it"))
    assert "100% of it (setting inner.radius_m: default 0.5 m; (0, 2])" in parser.format_help()
    with pytest.raises(KeyError, match="no setting 'radius_m'"):
        flag_help(Small, "radius_m")


def test_every_readme_table_matches_the_code() -> None:
    stale = settings_docs.check()
    assert not stale, "\n".join(stale) + f"\nrun '{settings_docs.FIX}'"


def test_every_settings_model_in_a_readme_describes_every_setting() -> None:
    missing = []
    for readme in settings_docs.readmes():
        for block in settings_docs.blocks(readme):
            model, section = settings_docs._model(block.spec, str(readme))
            missing += [f"{block.spec}: {r.name}" for r in setting_rows(model) if not r.description]
    assert not missing, "settings without a description:\n" + "\n".join(missing)


def _readme(tmp_path: Path, body: str) -> Path:
    readme = tmp_path / "pkg" / "README.md"
    readme.parent.mkdir()
    readme.write_text(f"# Pkg\n\n## Settings\n\n<!-- settings: {__name__}:Small -->\n{body}<!-- /settings -->\n")
    return readme


def test_check_names_the_stale_readme_and_write_fixes_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    readme = _readme(tmp_path, "| old | table |\n")
    assert settings_docs.main(["--check", "--root", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert f"pkg/README.md: settings of {__name__}:Small differ from the code" in err and "--write" in err
    assert settings_docs.main(["--write", "--root", str(tmp_path)]) == 0
    assert "| `inner.radius_m` |" in readme.read_text() and readme.read_text().startswith("# Pkg\n")
    assert settings_docs.main(["--check", "--root", str(tmp_path)]) == 0


def test_a_bad_marker_is_an_error_naming_the_fix(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    readme = _readme(tmp_path, "")
    readme.write_text(readme.read_text().replace(":Small", ":Nothing"))
    assert settings_docs.main(["--check", "--root", str(tmp_path)]) == 2
    assert "names no settings model" in capsys.readouterr().err
    readme.write_text("<!-- settings: x:Y -->\nno end\n")
    assert settings_docs.main(["--check", "--root", str(tmp_path)]) == 2
    assert "has no '<!-- /settings -->'" in capsys.readouterr().err


@pytest.mark.parametrize("command, flag_text", [
    ("detector", "(setting hog.upsample: default 1.0; [0.25, 8])"),
    ("localizer", "(setting min_depth_m: default 0.3 m; ≥ 0)"),
    ("simulate", "(setting fps: default 15.0 Hz; (0, 120])"),
])
def test_a_commands_help_lists_its_settings_from_the_declaration(command: str, flag_text: str) -> None:
    from perception.cli import build_parser

    sub = next(a for a in build_parser(only=command)._actions if isinstance(a, argparse._SubParsersAction))
    text = sub.choices[command].format_help()
    assert " ".join(flag_text.split()) in " ".join(text.split()) and "settings (defaults; --service-config" in text


class _Tuned(AdvancedBlock):
    model_config = ConfigDict(extra="forbid")

    rate_hz: float = setting(10.0, "output rate", unit="Hz", gt=0.0)
    gain: float = setting(3.0, "a filter's gain", ge=0.0, advanced=True)


class _Node(AdvancedBlock):
    model_config = ConfigDict(extra="forbid")

    port: int = setting(7447, "the port")
    inner: _Tuned = setting(default_factory=_Tuned, description="the filter")


def test_advanced_settings_are_written_under_advanced_or_beside_the_others() -> None:
    nested = _Node.model_validate({"inner": {"rate_hz": 5.0, "advanced": {"gain": 1.5}}})
    flat = _Node.model_validate({"inner": {"rate_hz": 5.0, "gain": 1.5}})
    assert nested == flat and nested.inner.gain == 1.5
    for bad, says in (({"advanced": {"rate_hz": 5.0}}, "rate_hz (not advanced"),
                      ({"advanced": {"gian": 1.0}}, "gian (no such setting)"),
                      ({"gain": 1.0, "advanced": {"gain": 2.0}}, "gain given both"),
                      ({"advanced": [1]}, "must be a mapping")):
        with pytest.raises(ValidationError, match=re.escape(says)):
            _Node.model_validate({"inner": bad})
    rows = {r.name: r.written for r in setting_rows(_Node)}
    assert rows == {"port": "port", "inner.rate_hz": "inner.rate_hz", "inner.gain": "inner.advanced.gain"}
    assert "`inner.advanced.gain`" in markdown_table(_Node) and "inner.advanced.gain = 3.0" in settings_epilog(_Node, "x")


def test_the_trackers_advanced_settings_go_under_advanced() -> None:
    from services.tracker.config import TrackerConfig

    cfg = TrackerConfig.model_validate({"robust": {"gate_sq": 9.2, "advanced": {"q_accel": 2.0},
                                                   "recovery": {"advanced": {"p_recover": 0.6}}}})
    assert (cfg.robust.gate_sq, cfg.robust.q_accel, cfg.robust.recovery.p_recover) == (9.2, 2.0, 0.6)
    with pytest.raises(ValidationError, match="gate_sq \\(not advanced"):
        TrackerConfig.model_validate({"robust": {"advanced": {"gate_sq": 9.2}}})


def test_layers_that_write_an_advanced_setting_both_ways_merge(tmp_path: Path) -> None:
    from common.runtime.config import ConfigError, load_config

    file = tmp_path / "node.yaml"
    file.write_text("inner:\n  gain: 2.0\n")
    cfg = load_config(_Node, file, base={"inner": {"advanced": {"gain": 1.0}}})
    assert cfg.inner.gain == 2.0  # the file over the preset, whichever way each wrote it
    cfg = load_config(_Node, file, env_prefix="X", environ={"X__INNER__ADVANCED__GAIN": "4.0"})
    assert cfg.inner.gain == 4.0  # the environment over the file
    file.write_text("inner:\n  advanced:\n    rate_hz: 2.0\n")
    with pytest.raises(ConfigError, match=re.escape(f"{file}: inner: advanced: rate_hz (not advanced")):
        load_config(_Node, file)
