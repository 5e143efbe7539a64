"""Launch files: substitution, validation messages, the plan, backoff, and every file in deploy/."""

from __future__ import annotations

import signal
from pathlib import Path

import pytest
import yaml

from perception.cli import main as cli_main
from tools.launcher.launchfile import LaunchFileError, load_launch_file, substitute
from tools.launcher.plan import build_plan, connectable
from tools.launcher.supervisor import BackoffState, describe_exit, error_line, should_restart

ROOT = Path(__file__).resolve().parents[2]
DEPLOY = ROOT / "deploy"
DEPLOY_FILES = sorted(DEPLOY.glob("*.yaml"))


def _load(tmp_path: Path, text: str, environ: dict[str, str] | None = None):  # noqa: ANN202
    f = tmp_path / "launch.yaml"
    f.write_text(text)
    return load_launch_file(f, environ or {})


@pytest.mark.parametrize(("value", "env", "expected"), [
    ("${A}", {"A": "x"}, "x"),
    ("${A:-d}", {}, "d"),
    ("${A:-d}", {"A": ""}, "d"),
    ("${A-d}", {"A": ""}, ""),
    ("${A-d}", {}, "d"),
    ("tcp/${HOST:-192.168.1.20}:${PORT:-7447}", {"PORT": "7500"}, "tcp/192.168.1.20:7500"),
    ("cost $$5 and ${A}", {"A": "b"}, "cost $5 and b"),
    ("$HOME stays", {"HOME": "/x"}, "$HOME stays"),
    ("${A:-}", {}, ""),
])
def test_substitute(value: str, env: dict[str, str], expected: str) -> None:
    assert substitute({"k": [value]}, env) == {"k": [expected]}


def test_substitute_leaves_non_strings_and_names_the_missing_variable() -> None:
    assert substitute({"n": 3, "b": True, "x": None}, {}) == {"n": 3, "b": True, "x": None}
    with pytest.raises(LaunchFileError, match=r"services\[0\]\.exec\[1\]: environment variable MISSING is not set"):
        substitute({"services": [{"exec": ["a", "${MISSING}"]}]}, {})
    with pytest.raises(LaunchFileError, match="malformed reference"):
        substitute({"a": "${oops"}, {})


@pytest.mark.parametrize(("text", "message"), [
    ("services:\n  - {name: a, exec: [x], restart: sometimes}\n", r"services\[0\] \(a\)\.restart: Input should be"),
    ("services:\n  - {name: a, exec: [x]}\n  - {name: a, exec: [y]}\n", "service name 'a' is used twice"),
    ("router: {}\nservices:\n  - {name: router, exec: [x]}\n", "'router' is the router's name"),
    ("services:\n  - {name: a, exec: [x], backoff: {initial_s: 5, max_s: 1}}\n", r"backoff: max_s \(1.0\) must be at least"),
    ("services:\n  - {name: a, exec: [x], backoff: {initial_s: 0}}\n", r"backoff\.initial_s: Input should be greater than 0"),
    ("services:\n  - {name: 'a b', exec: [x]}\n", r"services\[0\] \(a b\)\.name: String should match"),
    ("services:\n  - {name: a}\n", "give exactly one of 'command'"),
    ("robot: a/b\nservices:\n  - {name: a, exec: [x]}\n", "robot: robot name 'a/b'"),
    ("zenoh: {connect: [nowhere]}\nservices:\n  - {name: a, exec: [x]}\n", "zenoh.connect: endpoint 'nowhere'"),
    ("services:\n  - {name: a, exec: [x], config: missing.yaml}\n",
     r"services\[0\] \(a\)\.config: file .*missing.yaml does not exist"),
    ("routr: {}\n", "routr: Extra inputs are not permitted"),
    ("services:\n  - {name: off, exec: [x]}\n", r"name: Input should be a valid string; YAML reads .* quote the value"),
    ("{}\n", "nothing to launch"),
    ("- a\n", "must hold a mapping"),
])
def test_bad_launch_files_name_the_field(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(LaunchFileError, match=message):
        _load(tmp_path, text)


def test_plan_passes_zenoh_robot_and_config_and_writes_inline_configs(tmp_path: Path) -> None:
    (tmp_path / "given.yaml").write_text("tracker: {n_init: 2}\n")
    launch = _load(tmp_path, """
robot: ${ROBOT:-robot}
key_prefix: lab
env: {OMP_NUM_THREADS: 2}
router:
  listen: ["tcp/0.0.0.0:7450"]
  connect: [tcp/10.0.0.2:7447]
services:
  - {name: det, command: detector, config: {camera: head, threshold: 0.5}, args: [--camera, head]}
  - {name: trk, command: tracker, config: given.yaml, config_flag: --tracker-config, connect: [tcp/10.0.0.9:7447]}
  - {name: raw, exec: [drv, -v], config: {rate: 30}, config_section: "", env: {A: 1}}
  - {name: spare, exec: [x], enabled: false}
""", {"ROBOT": "mbot"})
    plan = build_plan(launch, {"PATH": "/bin"}, tmp_path / "cfg")
    assert [p.name for p in plan] == ["router", "det", "trk", "raw"]
    router, det, trk, raw = plan
    assert router.argv[3:] == ["router", "--listen=tcp/0.0.0.0:7450", "--connect=tcp/10.0.0.2:7447", "--no-multicast-scouting"]
    assert "--no-multicast-scouting" in router.argv and router.restart == "always" and router.stop_last
    assert router.ready_tcp == ("127.0.0.1", 7450)
    assert det.argv[3:] == ["detector", "--robot", "mbot", "--connect=tcp/127.0.0.1:7450", "--service-config",
                            str(tmp_path / "cfg" / "det.yaml"), "--camera", "head"]
    assert yaml.safe_load((tmp_path / "cfg" / "det.yaml").read_text()) == {"detector": {"camera": "head", "threshold": 0.5}}
    assert det.env["PERCEPTION_ROBOT"] == "mbot" and det.env["PERCEPTION_KEY_PREFIX"] == "lab"
    assert det.env["OMP_NUM_THREADS"] == "2" and det.env["PATH"] == "/bin" and det.env["PYTHONUNBUFFERED"] == "1"
    assert trk.argv[-2:] == ["--tracker-config", str(tmp_path / "given.yaml")]
    assert "--connect=tcp/10.0.0.9:7447" in trk.argv and trk.env["PERCEPTION_ZENOH_CONNECT"] == "tcp/10.0.0.9:7447"
    assert raw.argv == ["drv", "-v", "--service-config", str(tmp_path / "cfg" / "raw.yaml")]
    assert yaml.safe_load((tmp_path / "cfg" / "raw.yaml").read_text()) == {"rate": 30}
    assert raw.env["A"] == "1" and raw.env["PERCEPTION_ZENOH_CONNECT"] == "tcp/127.0.0.1:7450"


def test_only_selects_entries_and_rejects_unknown_names(tmp_path: Path) -> None:
    launch = _load(tmp_path, "router: {}\nservices:\n  - {name: a, exec: [x]}\n  - {name: b, exec: [y], enabled: false}\n")
    assert [p.name for p in build_plan(launch, {}, tmp_path)] == ["router", "a"]
    assert [p.name for p in build_plan(launch, {}, tmp_path, only=["b"])] == ["b"]
    assert [p.name for p in build_plan(launch, {}, tmp_path, only=["router", "a"])] == ["router", "a"]
    with pytest.raises(LaunchFileError, match=r"--only names 'c' not in the launch file \(entries: router, a, b\)"):
        build_plan(launch, {}, tmp_path, only=["c"])


def test_connectable_endpoints() -> None:
    assert connectable("tcp/0.0.0.0:7447") == "tcp/127.0.0.1:7447"
    assert connectable("tcp/[::]:7447") == "tcp/[::1]:7447"
    assert connectable("tcp/192.168.1.10:7447") == "tcp/192.168.1.10:7447"


def test_backoff_doubles_up_to_the_cap_and_resets_after_a_stable_run() -> None:
    b = BackoffState(initial_s=0.5, max_s=3.0, stable_after_s=10.0)
    assert [b.on_exit(1.0) for _ in range(5)] == [0.5, 1.0, 2.0, 3.0, 3.0]
    assert b.on_exit(12.0) == 0.5
    assert b.on_exit(0.1) == 1.0


def test_restart_policy_and_exit_descriptions() -> None:
    assert should_restart("always", 0) and should_restart("on-failure", 1) and should_restart("on-failure", -9)
    assert not should_restart("on-failure", 0) and not should_restart("never", 1)
    assert describe_exit(3) == "exit status 3"
    assert describe_exit(-signal.SIGKILL) == "killed by SIGKILL"


def test_exit_status_2_is_never_restarted_unless_the_launch_file_says_so(tmp_path: Path) -> None:
    assert not should_restart("always", 2) and not should_restart("on-failure", 2)
    assert should_restart("always", 2, no_restart=()) and not should_restart("always", 3, no_restart=(3,))
    f = tmp_path / "l.yaml"
    f.write_text("services:\n  - {name: a, command: tracker, restart: always}\n"
                 "  - {name: b, command: tracker, restart_prevent_exit_status: [2, 78]}\n"
                 "  - {name: c, command: tracker, restart_prevent_exit_status: []}\n")
    plan = build_plan(load_launch_file(f, {}), {}, tmp_path)
    assert [p.no_restart_status for p in plan] == [(2,), (2, 78), ()]
    f.write_text("services:\n  - {name: a, command: tracker, restart_prevent_exit_status: [0]}\n")
    with pytest.raises(LaunchFileError, match="restart_prevent_exit_status"):
        load_launch_file(f, {})


def test_error_line_is_the_last_perception_error_with_its_continuation() -> None:
    lines = ["starting", "perception: error: invalid tracker settings: camera 'a/b'", "(fix it in x.yaml or the flags)"]
    assert error_line(lines) == "perception: error: invalid tracker settings: camera 'a/b' (fix it in x.yaml or the flags)"
    assert error_line(["one", "Traceback", "  ValueError: boom  "]) == "ValueError: boom"
    assert error_line([]) == ""


def test_deploy_folder_has_the_expected_files() -> None:
    names = {p.relative_to(DEPLOY).as_posix() for p in DEPLOY.rglob("*") if p.is_file()}
    assert {"hri-pc.yaml", "nav-pc.yaml", "single-pc.yaml", "zenoh/router-hri-pc.json5", "zenoh/router-nav-pc.json5",
            "systemd/perception-launch@.service", "README.md"} <= names


@pytest.mark.parametrize("path", DEPLOY_FILES, ids=lambda p: p.name)
def test_every_deploy_file_validates_and_dry_runs(path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    launch = load_launch_file(path, {"ROBOT": "mbot"})
    assert launch.robot == "mbot" and launch.router is not None
    plan = build_plan(launch, {}, tmp_path)
    assert plan[0].name == "router" and "--no-multicast-scouting" in plan[0].argv
    assert cli_main(["launch", str(path), "--dry-run"]) == 0
    out = capsys.readouterr().out
    for p in plan:
        assert f". {p.name}: restart" in out


def test_deploy_split_covers_the_four_services_once() -> None:
    def commands(name: str) -> set[str]:
        return {s.command for s in load_launch_file(DEPLOY / name, {}).services if s.enabled and s.command}

    assert commands("hri-pc.yaml") == {"camera", "detector", "embedder"}
    assert commands("nav-pc.yaml") == {"localizer", "tracker"}
    assert commands("single-pc.yaml") == {"detector", "localizer", "embedder", "tracker"}
    hri = load_launch_file(DEPLOY / "hri-pc.yaml", {"HRI_PC": "10.0.0.1", "NAV_PC": "10.0.0.2"})
    nav = load_launch_file(DEPLOY / "nav-pc.yaml", {"HRI_PC": "10.0.0.1", "NAV_PC": "10.0.0.2"})
    assert hri.router is not None and nav.router is not None
    assert hri.router.listen == nav.router.connect == ["tcp/10.0.0.1:7447"]
    assert nav.router.listen == hri.router.connect == ["tcp/10.0.0.2:7447"]


@pytest.mark.parametrize("name", ["router-hri-pc.json5", "router-nav-pc.json5"])
def test_router_configs_load_with_multicast_off(name: str) -> None:
    import json

    import zenoh

    conf = zenoh.Config.from_file(str(DEPLOY / "zenoh" / name))
    assert json.loads(conf.get_json("mode")) == "router"
    assert json.loads(conf.get_json("scouting/multicast/enabled")) is False
    assert json.loads(conf.get_json("listen/endpoints")) and json.loads(conf.get_json("connect/endpoints"))


def test_a_launched_services_configuration_error_names_the_launch_file(tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    from common.runtime.cli_util import CliError
    from common.runtime.node import CONFIG_ORIGIN_ENV, load_node_config
    from services.tracker.config import TrackerConfig

    f = tmp_path / "robot.yaml"
    f.write_text("services:\n  - name: tracker\n    command: tracker\n    config:\n      output_rate_hz: -5\n")
    (spec,) = build_plan(load_launch_file(f, {}), {}, tmp_path / "cfg", origin=str(f))
    assert spec.env[CONFIG_ORIGIN_ENV] == f"{f}, the config of service 'tracker'"
    written = Path(spec.argv[spec.argv.index("--service-config") + 1])
    monkeypatch.setenv(CONFIG_ORIGIN_ENV, spec.env[CONFIG_ORIGIN_ENV])
    with pytest.raises(CliError) as err:
        load_node_config(TrackerConfig, "tracker", written, {})
    assert f"fix it in {f}, the config of service 'tracker'" in str(err.value) and str(written) not in str(err.value)
