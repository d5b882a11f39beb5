"""The court config loader: every key read into the dataclass, every wrong type/range/unknown key refused naming
the file, line and key (issue 12's misreads each included), flags checked the same way, and the CLI turning a
refusal into one line and exit 2 (real subprocess)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from engine.errors import CourtsideError, MalformedFileError
from gateway.court_config import CourtConfig, load_court_config, with_overrides

FULL = """\
listen = "127.0.0.2:7800"
record_dir = "takes"
record = "rally-01"
log_level = "debug"
name = "court-3"
max_clients = 4
handshake_timeout_s = 2.5
status_interval_s = 0.5
clock_lock_after_s = 10

[stations]
ports = ["/dev/ttyACM0", "hid:1209:c0de"]
urls = ["emu://a?sensors=6"]
discover = true
emulate = 2
emulate_motion = "none"
emulate_clips = ["16_01", "moves/rally.bvh"]

[camera]
source = 0
court = "court.json"
player_side = "far"
fps = 30
latency_s = 0.04
loop = true
thumbnail_every = 5

[calibration]
placements = ["left_forearm", "chest"]
pose = "tpose"
records_dir = "/var/lib/courtside/calibrations"

[auth]
operator_secret_file = "secrets/operator"
viewer_secret_file = "secrets/viewer"
tls_cert = "tls/cert.pem"
tls_key = "tls/key.pem"
"""


def write(tmp_path: Path, text: str, name: str = "court.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_every_key_is_read_and_relative_paths_follow_the_file(tmp_path):
    config = load_court_config(write(tmp_path, FULL))
    assert config.listen == ("127.0.0.2", 7800) and config.record == "rally-01" and config.log_level == "DEBUG"
    assert config.record_dir == tmp_path / "takes"  # relative to the config file, not the cwd
    assert (config.name, config.max_clients, config.handshake_timeout_s) == ("court-3", 4, 2.5)
    assert config.status_interval_s == 0.5 and config.clock_lock_after_s == 10.0
    st = config.stations
    assert st.ports == ("/dev/ttyACM0", "hid:1209:c0de") and st.urls == ("emu://a?sensors=6",)
    assert st.discover is True and st.emulate == 2 and st.emulate_motion == "none"
    assert st.emulate_clips == ("16_01", str(tmp_path / "moves/rally.bvh"))  # files resolve like paths
    cam = config.camera
    assert cam.source == 0 and cam.court == tmp_path / "court.json" and cam.player_side == "far"
    assert (cam.fps, cam.latency_s, cam.loop, cam.thumbnail_every) == (30.0, 0.04, True, 5)
    cal = config.calibration
    assert cal.placements == ("left_forearm", "chest") and cal.pose == "tpose"
    assert cal.records_dir == Path("/var/lib/courtside/calibrations")
    assert config.auth.operator_secret_file == tmp_path / "secrets/operator"
    assert config.auth.tls_key == tmp_path / "tls/key.pem"
    assert config.authenticated


def test_a_relative_camera_file_is_next_to_the_config(tmp_path):
    config = load_court_config(write(tmp_path, '[camera]\nsource = "videos/court.mp4"\ncourt = "c.json"\n'))
    assert config.camera.source == str(tmp_path / "videos/court.mp4")
    config = load_court_config(write(tmp_path, '[camera]\nsource = "/dev/video2"\ncourt = "c.json"\n'))
    assert config.camera.source == "/dev/video2"


def test_an_empty_file_gives_the_defaults(tmp_path):
    assert load_court_config(write(tmp_path, "")) == CourtConfig()
    assert CourtConfig().listen == ("127.0.0.1", 7766) and not CourtConfig().authenticated


@pytest.mark.parametrize("text, line, fragment", [
    # issue 12's silent misreads and tracebacks
    ('[stations]\nports = "/dev/ttyX"\n', 2, "stations.ports: expected a list of strings"),
    ('[stations]\ndiscover = "no"\n', 2, "stations.discover: expected true or false"),
    ('[stations]\nemulate = -1\n', 2, "stations.emulate: -1 is out of range 0..16"),
    ('[stations]\nemulate = "two"\n', 2, "stations.emulate: expected an integer"),
    ('[stations]\nemulate = true\n', 2, "stations.emulate: expected an integer"),
    ('listen = 12\n', 1, "listen: expected a non-empty string"),
    ('listen = "127.0.0.1:99999"\n', 1, "port 99999 is out of range"),
    ('listen = "localhost"\n', 1, "expected \"host:port\""),
    ('record_dir = 5\n', 1, "record_dir: expected a non-empty string"),
    ('[ports]\na = 1\n', 1, "ports: unknown key (it belongs in the [stations] table)"),
    ('ports = ["/dev/ttyACM0"]\n', 1, "it belongs in the [stations] table"),
    ('stations = 3\n', 1, "stations: expected a [stations] table"),
    ('[stations]\nport = ["/dev/x"]\n', 2, "stations.port: unknown key"),
    ('[stations]\nports = ["ok", 3]\n', 2, "item 1 is an integer 3"),
    ('colour = "red"\n', 1, "colour: unknown key"),
    ('log_level = "loud"\n', 1, "log_level: expected one of"),
    ('record = "../escape"\n', 1, "record: take name '../escape' contains a path separator"),
    ('record = ".."\n', 1, "starts with a dot"),
    ('max_clients = 0\n', 1, "max_clients: 0 is out of range 1..1024"),
    ('handshake_timeout_s = 0\n', 1, "handshake_timeout_s: 0 is out of range"),
    # issue 22: every duration and rate has a physical bound; NUL bytes are refused naming the key
    ('handshake_timeout_s = 1e-300\n', 1, "handshake_timeout_s: 1e-300 is out of range (>= 0.1"),
    ('status_interval_s = 1e-9\n', 1, "status_interval_s: 1e-09 is out of range (>= 0.05"),
    ('[camera]\nfps = 1e-300\n', 2, "camera.fps: 1e-300 is out of range (>= 1"),
    ('record_dir = "rec\\u0000ordings"\n', 1, "record_dir: contains a NUL byte"),
    ('[auth]\noperator_secret_file = "a\\u0000b"\n', 2, "auth.operator_secret_file: contains a NUL byte"),
    ('[stations]\nports = ["/dev/tty\\u0000S0"]\n', 2, "stations.ports: item 0"),
    ('name = "court\\u0000"\n', 1, "name: contains a NUL byte"),
    ('status_interval_s = nan\n', 1, "status_interval_s: nan is out of range"),
    ('[camera]\nsource = -2\ncourt = "c.json"\n', 2, "camera.source: -2 is out of range 0..63"),
    ('[camera]\nsource = "x.mp4"\ncourt = "c.json"\nplayer_side = "left"\n', 4, "camera.player_side: expected one of"),
    ('[camera]\nfps = "30"\n', 2, "camera.fps: expected a number"),
    ('[camera]\nloop = 1\n', 2, "camera.loop: expected true or false"),
    ('[calibration]\nplacements = ["left_forearm", "tail"]\n', 2, "unknown sensor site(s) ['tail']"),
    ('[calibration]\nplacements = ["chest", "chest"]\n', 2, "listed twice"),
    ('[calibration]\npose = "apose"\n', 2, "calibration.pose: expected one of"),
    ('[auth]\npassword = "hunter2"\n', 2, "auth.password: unknown key"),
    ('listen = "127.0.0.1:7766\n', 1, "not valid TOML"),
])
def test_refusals_name_the_file_line_and_key(tmp_path, text, line, fragment):
    path = write(tmp_path, text)
    with pytest.raises(MalformedFileError) as info:
        load_court_config(path)
    assert info.value.path == str(path) and info.value.line == line, str(info.value)
    assert fragment in str(info.value), str(info.value)


@pytest.mark.parametrize("text, fragment", [
    ('listen = "0.0.0.0:7766"\n', r"beyond loopback\) needs authentication"),
    ('listen = "192.168.1.20:7766"\n', r"beyond loopback\) needs authentication"),
    ('[camera]\nsource = "clip.mp4"\n', "camera.court is not"),
    ('[auth]\nviewer_secret_file = "v"\n', "needs auth.operator_secret_file"),
    ('[auth]\noperator_secret_file = "o"\ntls_cert = "c.pem"\n', "TLS needs both"),
    ('[auth]\noperator_secret_file = "s"\nviewer_secret_file = "./s"\n',
     "auth.viewer_secret_file and auth.operator_secret_file are the same file"),
])
def test_rules_across_keys(tmp_path, text, fragment):
    with pytest.raises(MalformedFileError, match=fragment):
        load_court_config(write(tmp_path, text))


def test_a_binary_or_missing_file_is_refused_by_name(tmp_path):
    binary = tmp_path / "court.toml"
    binary.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(MalformedFileError, match="not a text"):
        load_court_config(binary)
    with pytest.raises(MalformedFileError, match="cannot read"):
        load_court_config(tmp_path / "absent.toml")


def test_flags_override_the_file_and_are_checked_the_same_way(tmp_path):
    config = load_court_config(write(tmp_path, '[stations]\nemulate = 2\nports = ["/dev/a"]\n'))
    config = with_overrides(config, {"stations.emulate": 1, "stations.ports": ["/dev/b", "/dev/c"],
                                     "camera.source": "7", "camera.court": "c.json", "listen": None})
    assert config.stations.emulate == 1 and config.stations.ports == ("/dev/b", "/dev/c")
    assert config.camera.source == 7 and config.camera.court == Path("c.json") and config.listen[1] == 7766
    with pytest.raises(CourtsideError, match="--emulate: -1 is out of range"):
        with_overrides(config, {"stations.emulate": -1}, {"stations.emulate": "--emulate"})
    with pytest.raises(CourtsideError, match="beyond loopback"):
        with_overrides(config, {"listen": "0.0.0.0:7766"})
    # a flag can complete what the file lacks: the secret for a non-loopback listen address
    file_only = load_court_config(write(tmp_path, 'listen = "0.0.0.0:7766"\n', "open.toml"), check=False)
    assert with_overrides(file_only, {"auth.operator_secret_file": "s"}).authenticated


def _gateway_cli(*args: str, cwd: Path, preexec_fn=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "gateway.cli", "gateway", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=60, preexec_fn=preexec_fn)


def _no_file_writes() -> None:
    """In the child: every write to a file fails with EFBIG, as on a full disk (a full quota)."""
    import resource
    import signal

    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (0, 0))


def test_cli_refuses_a_bad_config_with_one_line_and_exit_2(tmp_path):
    path = write(tmp_path, '[stations]\nports = "/dev/ttyX"\n')
    result = _gateway_cli("--config", str(path), cwd=tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert result.stderr.strip().count("\n") == 0, result.stderr
    assert str(path) in result.stderr and "stations.ports" in result.stderr
    result = _gateway_cli("--listen", "0.0.0.0:7766", cwd=tmp_path)
    assert result.returncode == 2 and "needs authentication" in result.stderr and "Traceback" not in result.stderr
    # a rule across keys broken by the file alone names the file (it did not: only the flag case is nameless)
    path = write(tmp_path, 'listen = "0.0.0.0:7766"\n')
    result = _gateway_cli("--config", str(path), cwd=tmp_path)
    assert result.returncode == 2 and result.stderr.strip().count("\n") == 0, result.stderr
    assert result.stderr.startswith(f"courtside gateway: {path}: listening on 0.0.0.0:7766 (beyond loopback) needs")


def test_shipped_example_config_loads_and_every_key_is_documented():
    from dataclasses import fields

    from gateway.athletes import AthleteConfig
    from gateway.court_config import AuthConfig, CalibrationConfig, CameraConfig, LslConfig, StationsConfig

    root = Path(__file__).resolve().parents[2]
    example = root / "docs" / "deploy" / "court.example.toml"
    config = load_court_config(example)
    assert config.authenticated and config.camera.source == "/dev/video0" and config.stations.discover
    text, docs = example.read_text(), (root / "docs" / "gateway.md").read_text()
    sections = {"": CourtConfig, "[stations] ": StationsConfig, "[camera] ": CameraConfig,
                "[calibration] ": CalibrationConfig, "[auth] ": AuthConfig, "[lsl] ": LslConfig,
                "[[athletes]] ": AthleteConfig}
    assert [a.name for a in config.athletes] == ["alice", "bob"] and config.athletes[1].sensors[0].key == "sn"
    for prefix, cls in sections.items():
        for f in fields(cls):
            if f.name in ("stations", "camera", "calibration", "auth", "lsl", "athletes"):
                continue  # the tables themselves
            assert f"\n{f.name} =" in text, f"{f.name} missing from {example.name}"
            assert f"`{prefix}{f.name}`" in docs or f"`{prefix}{f.name}`," in docs or f", `{f.name}`" in docs, f.name
    unit = (root / "docs" / "deploy" / "courtside-gateway.service").read_text()
    assert "--config /etc/courtside/court.toml" in unit and "RestartPreventExitStatus=2" in unit


def test_cli_exit_1_when_it_cannot_start_now(tmp_path):
    """Exit 1 (a service manager retries): the address is taken, or a live camera is not there (yet)."""
    import socket

    import numpy as np

    from gateway.camera.court import COURT_KEYPOINTS_M, keypoints_array
    from gateway.camera.court_calibration import CourtCalibration
    from gateway.camera.synthetic import default_court_camera

    with socket.create_server(("127.0.0.4", 0)) as taken:
        result = _gateway_cli("--listen", f"127.0.0.4:{taken.getsockname()[1]}", cwd=tmp_path)
    assert result.returncode == 1 and "cannot start" in result.stderr and "Traceback" not in result.stderr
    camera = default_court_camera((320, 180))
    names = list(COURT_KEYPOINTS_M)
    clicks = camera.project(np.column_stack([keypoints_array(names), np.zeros(len(names))]))
    CourtCalibration.fit(clicks, names=names, image_size=camera.image_size).save(tmp_path / "court.json")
    result = _gateway_cli("--camera", "/dev/video63", "--court", "court.json", "--listen", "127.0.0.4:0", cwd=tmp_path)
    assert result.returncode == 1 and "/dev/video63" in result.stderr and "Traceback" not in result.stderr
    result = _gateway_cli("--camera", "63", "--court", "court.json", "--listen", "127.0.0.4:0", cwd=tmp_path)
    assert result.returncode == 1 and "camera 63: cannot open" in result.stderr
    assert "WARN" not in result.stderr, result.stderr  # OpenCV's own "can't open camera by index" lines
    result = _gateway_cli("--camera", "/dev/video63", "--court", "absent.json", cwd=tmp_path)
    assert result.returncode == 2 and "absent.json" in result.stderr
    # the first take cannot be started now (a full disk): exit 1, a restart may help
    result = _gateway_cli("--record-dir", "rec", "--record", "x", "--listen", "127.0.0.4:0", cwd=tmp_path,
                          preexec_fn=_no_file_writes)
    assert result.returncode == 1 and "cannot start recording" in result.stderr and "Traceback" not in result.stderr
    # a record_dir that is a file is a bad config, not a passing fault (issue 22: it exited 1): exit 2, one line
    (tmp_path / "not-a-dir").write_text("")
    result = _gateway_cli("--record-dir", "not-a-dir", "--record", "x", "--listen", "127.0.0.4:0", cwd=tmp_path)
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert "--record-dir: " in result.stderr and "not-a-dir exists and is not a directory" in result.stderr
    config = write(tmp_path, 'record_dir = "not-a-dir"\n')
    result = _gateway_cli("--config", str(config), "--duration", "0", cwd=tmp_path)
    assert result.returncode == 2 and f"{config}, line 1: record_dir: " in result.stderr, result.stderr


def test_a_config_built_in_code_is_checked_too(tmp_path):
    """The demo builds its CourtConfig in code; build_court still refuses an unauthenticated open listener."""
    from gateway.assembly import build_court

    with pytest.raises(CourtsideError, match="beyond loopback"):
        build_court(CourtConfig(listen=("0.0.0.0", 0), record_dir=tmp_path))


def test_record_dir_that_is_a_file_is_a_bad_config(tmp_path):
    (tmp_path / "file").write_text("")
    path = write(tmp_path, 'record_dir = "file"\n\n[calibration]\nrecords_dir = "."\n')
    with pytest.raises(MalformedFileError, match=r"line 1: record_dir: .*file exists and is not a directory"):
        load_court_config(path)
    with pytest.raises(CourtsideError, match="--record-dir: .* is not a directory"):
        with_overrides(CourtConfig(), {"record_dir": str(tmp_path / "file")}, {"record_dir": "--record-dir"})


def test_one_secret_in_two_files_is_refused_naming_both(tmp_path):
    from gateway import auth

    auth.write_secret_file(tmp_path / "op")
    (tmp_path / "viewer").write_bytes((tmp_path / "op").read_bytes())
    (tmp_path / "viewer").chmod(0o600)
    with pytest.raises(MalformedFileError) as info:
        auth.Secrets.from_files(tmp_path / "op", tmp_path / "viewer")
    assert info.value.path == str(tmp_path / "viewer") and str(tmp_path / "op") in str(info.value)
    assert "viewer_secret_file holds the same secret as operator_secret_file" in str(info.value)
