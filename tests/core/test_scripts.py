"""headless/simulate.py and headless/bench.py run as scripts on tiny fields (numpy only)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from windgrass.grass_addon import schema
from windgrass.grass_addon.solver import SolverState

pytestmark = pytest.mark.slow  # each test starts Python again (dev.py test --quick leaves them out)

REPO = Path(__file__).resolve().parents[2]
TINY = ["--field-blocks-x", "2", "--field-blocks-y", "1", "--field-cells-per-block", "4",
        "--field-blades-per-cell", "3", "--blade-segments", "4"]


def run(script, *args, timeout=300):
    return subprocess.run([sys.executable, str(REPO / "headless" / script), *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, cwd=REPO)


@pytest.fixture(scope="module")
def trace(tmp_path_factory):
    path = tmp_path_factory.mktemp("sim") / "trace.npz"
    proc = run("simulate.py", *TINY, "--frames", 6, "--fps", 12, "--wind-speed", 8.0, "--trace", path)
    assert proc.returncode == 0, proc.stderr
    with np.load(path) as data:
        return {k: data[k] for k in data.files}, proc.stdout


def test_trace_has_documented_keys_shapes_and_units(trace):
    tr, _ = trace
    F, Ny, Nx, n, B = 6, 4, 8, 4, 4 * 8 * 3
    documented = (REPO / "docs" / "headless.md").read_text()
    for key in tr:
        assert f"`{key}`" in documented, f"trace key {key} is not documented in docs/headless.md"
    shapes = {"frame": (F,), "time": (F,), "wind_speed": (F,), "wind_direction": (F,),
              "cell_wind": (F, Ny, Nx, 2), "cell_bend": (F, Ny, Nx, n), "cell_bend_vector": (F, Ny, Nx, n, 2),
              "cell_twist": (F, Ny, Nx, n), "card_offset": (F, Ny, Nx, 3), "cell_x": (Nx,), "cell_y": (Ny,),
              "blade_tip": (F, B, 3), "blade_root": (B, 3), "blade_rest_tip": (B, 3),
              "tip_displacement_mean": (F,), "tip_displacement_max": (F,)}
    for key, shape in shapes.items():
        assert tr[key].shape == shape, key
    # time in seconds at 12 fps from the first frame
    np.testing.assert_allclose(tr["time"], np.arange(F) / 12.0)
    np.testing.assert_array_equal(tr["frame"], np.arange(1, F + 1))
    # cells are 0.1 m apart, centred on the origin
    np.testing.assert_allclose(np.diff(tr["cell_x"]), 0.1, rtol=1e-5)
    np.testing.assert_allclose(tr["cell_x"].mean(), 0.0, atol=1e-6)
    # mean wind: 8 m/s (the flag) towards 30 degrees (the default), in radians
    np.testing.assert_allclose(tr["wind_speed"], 8.0, rtol=1e-5)
    np.testing.assert_allclose(tr["wind_direction"], np.radians(30.0), rtol=1e-5)
    # the params round-trip, with the flags applied
    params = schema.loads_toml(str(tr["params_toml"]))
    assert params.wind.speed == 8.0 and params.render.fps == 12 and params.field.blocks_x == 2


def test_trace_physics_is_consistent(trace):
    tr, _ = trace
    d = tr["wind_direction"][:, None, None, None]
    v = tr["cell_bend_vector"]
    np.testing.assert_allclose(tr["cell_bend"], v[..., 0] * np.cos(d) + v[..., 1] * np.sin(d), atol=1e-6)
    # an 8 m/s wind bends the grass downwind on average
    assert tr["cell_bend"].sum(axis=3).mean() > 0.0
    # the mean cell wind is close to the mean wind vector (turbulence averages out over cells)
    mean_wind = tr["cell_wind"].mean(axis=(0, 1, 2))
    np.testing.assert_allclose(np.linalg.norm(mean_wind), 8.0, rtol=0.35)
    # rigid segments: no tip is farther from its root than its blade is long, tips stay above ground
    lay_len = np.linalg.norm(tr["blade_rest_tip"] - tr["blade_root"], axis=1)
    reach = np.linalg.norm(tr["blade_tip"] - tr["blade_root"][None], axis=2)
    assert np.all(reach <= 1.5 * 0.32 * 3)  # generous: lengths are l_base + 0.07 N(0,1)
    assert np.all(lay_len > 0.0)
    disp = np.linalg.norm(tr["blade_tip"] - tr["blade_rest_tip"][None], axis=2)
    np.testing.assert_allclose(tr["tip_displacement_max"], disp.max(axis=1), rtol=1e-5)


def test_summary_names_the_field_and_the_numbers(trace):
    _, out = trace
    for word in ("blades", "96", "gentle_breeze", "8 m/s", "frames", "ms per frame", "bend", "tips"):
        assert word in out, word
    assert len(out.splitlines()) <= 24  # one screen


def test_config_file_is_read(tmp_path):
    cfg = tmp_path / "scene.toml"
    cfg.write_text("[field]\nblocks_x = 1\nblocks_y = 1\ncells_per_block = 2\n[wind]\nspeed = 1.5\n")
    proc = run("simulate.py", "--config", cfg, "--frames", 2)
    assert proc.returncode == 0, proc.stderr
    assert "1.5 m/s" in proc.stdout and "4 cells" in proc.stdout


@pytest.mark.parametrize("args, name", [
    (["--wind-speed", "-1"], "wind.speed"),
    (["--frames", "0"], "frames"),
    (["--config", "/nonexistent/scene.toml"], "config"),
    (["--field-blocks-x", "2.5"], "field.blocks_x"),
    (["--lod-blade-far", "1", "--lod-blade-near", "3"], "lod.blade_far"),
    (["--trace", "/tmp"], "trace"),
    (["--trace", "/proc/windgrass-trace.npz"], "trace"),
    (["--lod-enabled", "perhaps"], "--lod-enabled"),
])
def test_bad_input_exits_2_naming_the_parameter(args, name):
    proc = run("simulate.py", *TINY, "--frames", 1, *args)
    assert proc.returncode == 2
    assert name in proc.stderr
    assert "Traceback" not in proc.stderr and "_parse" not in proc.stderr


def _scene_file(tmp_path, kind):
    if kind == "pipe":
        path = tmp_path / "scene.toml"
        os.mkfifo(path)  # (nothing ever writes to it: reading would wait forever)
        return path
    if kind == "device":
        return "/dev/zero"  # (endless: reading it all took 3 GB)
    path = tmp_path / "scene.toml"
    if kind == "deep key":  # 39 KB: Python's TOML parser took 2.3 GB for it
        path.write_text("[wind]\n" + ".".join(["a"] * 20000) + " = 1\n")
    else:  # "huge": a 5 MB file of comments
        path.write_text(("# " + "x" * 98 + "\n") * 50000)
    return path


@pytest.mark.parametrize("kind, words", [("pipe", "not a regular file"), ("device", "not a regular file"),
                                         ("deep key", "20000 dotted parts"), ("huge", "at most 4,194,304")])
def test_a_scene_file_that_is_no_scene_file_is_refused_at_once(tmp_path, kind, words):
    """Issue #37 item 8: a pipe hung simulate.py, /dev/zero took 3 GB, and a key dotted a few
    thousand deep took gigabytes in the TOML parser; each is refused in a moment, naming --config."""
    proc = run("simulate.py", "--config", _scene_file(tmp_path, kind), "--frames", 1, timeout=60)  # (no hang)
    assert proc.returncode == 2 and "config" in proc.stderr and words in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize("line, words", [
    ("density = 1", "valid 100 to 6400 1/m^2 (or 0)"),  # (at the default 0.1 m cell: whole blades per cell)
    ("density = 1e6", "valid 100 to 6400 1/m^2 (or 0)"),
    ("size_x = 0.5", "valid 1.6 to 16384 m"),  # (whole blocks of 16 cells of 0.1 m)
])
def test_a_density_or_size_a_field_cannot_have_is_refused_naming_its_range(tmp_path, line, words):
    """Issue #37 item 9: density = 1 gave a field without a blade, 1e6 one of 6,400 per m^2."""
    cfg = tmp_path / "scene.toml"
    cfg.write_text(f"[field]\n{line}\n")
    proc = run("simulate.py", "--config", cfg, "--frames", 1, timeout=60)
    assert proc.returncode == 2 and f"field.{line.split()[0]}" in proc.stderr and words in proc.stderr, proc.stderr


def test_a_files_size_stays_in_metres_when_a_flag_changes_the_cell_size(tmp_path):
    """Issue #37 item 9: size_x = 20 with --field-cell-size 0.2 gave a 40 m field. The file's 20 m
    and 10 m hold (to whole blocks: 16 cells of 0.2 m are 3.2 m, so 19.2 m and 9.6 m), and a flag
    for the blocks replaces the file's size."""
    cfg = tmp_path / "scene.toml"
    cfg.write_text("[field]\nsize_x = 20\nsize_y = 10\nblades_per_cell = 1\n")
    proc = run("simulate.py", "--config", cfg, "--field-cell-size", "0.2", "--field-blocks-y", "2", "--frames", 1,
               timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "19.2 x 6.4 m" in proc.stdout, proc.stdout


# numpy's savez leaves its ZipFile to the garbage collector when a value fails to serialise
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_a_failed_trace_write_keeps_the_earlier_trace(tmp_path):
    """The trace is written beside its name and renamed: a write that fails half-way (here an
    array that cannot be serialised, after others were written) leaves the good trace as it was."""
    import simulate

    path = tmp_path / "trace.npz"
    simulate.write_trace(path, {"frame": np.arange(3)})
    good = path.read_bytes()
    unpicklable = np.array([lambda: None], dtype=object)
    with pytest.raises(Exception):  # noqa: B017 (whatever pickle raises for a lambda)
        simulate.write_trace(path, {"frame": np.arange(1000), "bad": unpicklable})
    assert path.read_bytes() == good
    assert [p.name for p in tmp_path.iterdir()] == ["trace.npz"]
    with np.load(path) as data:
        np.testing.assert_array_equal(data["frame"], np.arange(3))


def test_bench_prints_one_json_object():
    proc = run("bench.py", "--blades", 1024, "--segments", 3, "--frames", 2, "--json")
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result["blades"] == 1024 and result["segments"] == 3 and result["cells"] == 512
    assert set(result["phases_ms"]) == {"wind", "solver", "lod", "kinematics"}
    assert all(v >= 0 for v in result["phases_ms"].values())
    np.testing.assert_allclose(result["frame_update_ms"], sum(result["phases_ms"].values()), atol=0.01)
    assert result["floor_copy_ms"] > 0
    # the JSON rounds the times to 0.001 ms; the ratio is taken before rounding
    floor, update = result["floor_copy_ms"], result["frame_update_ms"]
    assert (update - 0.003) / (floor + 0.0005) * 0.99 <= result["ratio_to_floor"] <= \
        (update + 0.003) / max(floor - 0.0005, 1e-9) * 1.01
    # the state copied by the floor is every SolverState array: at least bend, bend_vel (2 floats per
    # joint), twist, twist_vel (1 each), i.e. 6 float32 per joint per cell, plus any other state array
    state = SolverState(512, 3)
    arrays = [v for v in vars(state).values() if isinstance(v, np.ndarray)]
    assert result["floor_copy_bytes"] == sum(a.nbytes for a in arrays) >= 512 * 3 * 6 * 4
    for key in ("build_ms", "machine"):
        assert key in result
    assert "peers" not in result


def test_bench_rejects_bad_counts():
    proc = run("bench.py", "--blades", 0)
    assert proc.returncode == 2 and "blades" in proc.stderr


def test_bench_peers_missing_module_is_reported(monkeypatch):
    """--peers merges bench_peers.run_peers() under "peers"; without that module the JSON says so."""
    import bench

    monkeypatch.setitem(sys.modules, "bench_peers", None)  # import of a None entry raises ImportError
    result = bench.run_peers_json()
    assert "error" in result and "bench_peers" in result["error"]


def test_wind_type_flag_brings_its_preset_speed():
    """--wind-type calm without --wind-speed means a calm (Beaufort 0, < 0.5 m/s), not the
    default breeze speed; an explicit --wind-speed still wins."""
    calm = run("simulate.py", *TINY, "--frames", 1, "--wind-type", "calm")
    assert calm.returncode == 0, calm.stderr
    assert f"calm, {schema.WIND_TYPE_PRESETS['calm']['speed']:g} m/s" in calm.stdout
    given = run("simulate.py", *TINY, "--frames", 1, "--wind-type", "calm", "--wind-speed", "2")
    assert "calm, 2 m/s" in given.stdout


def test_a_traced_rolling_ball_has_no_blade_tip_inside_it(tmp_path):
    """simulate.py on a scene file with a ball of 0.4 m rolling through calm grass: the traced tips
    (the blades as drawn) are never inside the ball by more than the tolerance, though without
    the ball many would be."""
    cfg = tmp_path / "ball.toml"
    cfg.write_text("""
[field]
blocks_x = 2
blocks_y = 2
cells_per_block = 8
cell_size = 0.1
blades_per_cell = 4
[wind]
speed = 0.0
turbulence = 0.0
[render]
fps = 24
[[colliders]]
radius = 0.4
path = [{time = 0.0, position = [-1.2, 0.0, 0.4]}, {time = 1.0, position = [1.2, 0.0, 0.4]}]
""")
    path = tmp_path / "trace.npz"
    proc = run("simulate.py", "--config", cfg, "--frames", 24, "--trace", path)
    assert proc.returncode == 0, proc.stderr
    with np.load(path) as data:
        tips, times, rest = data["blade_tip"].astype(np.float64), data["time"], data["blade_rest_tip"]
    x = -1.2 + 2.4 * np.clip(times, 0.0, 1.0)  # the ball's centre along its path
    centres = np.column_stack([x, np.zeros_like(x), np.full_like(x, 0.4)])
    depth = 0.4 - np.linalg.norm(tips - centres[:, None, :], axis=2)
    assert depth.max() < 0.01, depth.max()  # interaction.tolerance
    rest_depth = 0.4 - np.linalg.norm(rest[None].astype(np.float64) - centres[:, None, :], axis=2)
    assert (rest_depth > 0.01).sum() > 200


@pytest.mark.parametrize("args", [["--views", "strip", "--heights", "1.1", "200"], ["--presets", "painted", "bogus"]])
def test_a_refused_lod_comparison_leaves_nothing_behind(tmp_path, args):
    """Issue #62: dev.py lod --views strip --heights 1.1 200 --out X exited 2 (bad input) but
    left X/painted_density.png, the painted preset's map written while the settings were checked."""
    out = tmp_path / "lod"
    extra = [] if "--presets" in args else ["--presets", "painted"]
    proc = run("lod_compare.py", *args, *extra, "--out", out)
    assert proc.returncode == 2 and "lod_compare.py: error:" in proc.stderr, proc.stderr
    assert not out.exists() or not list(out.iterdir())


def test_dev_py_help_exits_0_and_a_missing_job_2():
    """Issue #62: dev.py --help and -h printed the usage and exited 2, as for a mistake."""
    for flags, code in ((["--help"], 0), (["-h"], 0), ([], 2), (["nope"], 2)):
        proc = subprocess.run([sys.executable, str(REPO / "dev.py"), *flags], capture_output=True, text=True,
                              timeout=60)
        assert "dev.py test --quick" in proc.stdout and proc.returncode == code, (flags, proc.returncode)
