"""The user's install (issue 18 acceptance, docs/packaging.md): `python -m build` makes the sdist
and, from it, the wheel with the compiled parts; the wheel installed into a fresh virtual
environment outside the checkout runs, as a user who is not root and with no compiler on PATH,
`--version`, `simulate`, `estimate` (array-ekf and the wheel's firmware library), `plot`,
`record` + `replay --verify` on the wheel's native virtual board and `live --json-lines` against
it; with the parts hidden the pure-Python commands still work and the others say in one line
what to install. The sdist installs into fresh environments: where CMake cannot find simavr and
libelf it still compiles the three parts (none needs them); where no compiler works (CC and CXX
a compiler that fails, as macOS's `c++` without the command-line tools) it makes a pure-Python
wheel whose host runs and says in one line which part it lacks. The wheel's CMake project,
configured without simavr, libelf and Eigen, skips the parts that need Eigen.

`python -m build` runs once a session (the `dist` fixture, shared by the xdist workers): about
four minutes in all on two cores, half of it the wheel's test, 40 s the sdist's CMake build."""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from jointangle.built import HIDE_ENV, REPO_ROOT

pytestmark = pytest.mark.slow
COMPILERS = ("cc", "c++", "gcc", "g++", "clang", "clang++", "cmake", "make", "ninja")
WHEEL_PARTS = ("libja_filter_replay.so", "libja_sim_devices.so", "ja_native_board")


def user_env(bin_dir: Path, home: Path) -> dict[str, str]:
    """What a user's shell has: the environment's bin/ on PATH and nothing of this checkout (no
    PYTHONPATH, no JOINTANGLE_* variables, no compiler)."""
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("JOINTANGLE_", "PYTHON", "VIRTUAL_ENV", "PYTEST", "COV_"))}
    env.update(PATH=str(bin_dir), HOME=str(home), MPLBACKEND="Agg")
    return env


def demote() -> list[str]:
    """The command prefix that runs as `nobody` when the tests run as root."""
    if os.geteuid() != 0:
        return []
    setpriv = shutil.which("setpriv")
    assert setpriv, "setpriv (util-linux) is needed to run the user's commands as non-root"
    return [setpriv, "--reuid=65534", "--regid=65534", "--clear-groups", "--"]


@pytest.fixture
def area() -> Iterator[Path]:
    """A folder outside the checkout that `nobody` may enter (pytest's tmp folders are 0700)."""
    d = Path(tempfile.mkdtemp(prefix="jointangle-wheel-"))
    d.chmod(0o755)
    assert REPO_ROOT not in d.parents
    yield d
    shutil.rmtree(d, ignore_errors=True)


def build_dist(out: Path) -> dict[str, Path]:
    """`python -m build`: the sdist, then the wheel built from that sdist."""
    if not (out / "built").is_file():
        res = subprocess.run([sys.executable, "-m", "build", "--outdir", str(out),
                              str(REPO_ROOT)], capture_output=True, text=True, check=False)
        assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
        (out / "built").touch()
    (wheel,), (sdist,) = out.glob("*.whl"), out.glob("*.tar.gz")
    return {"wheel": wheel, "sdist": sdist}


@pytest.fixture(scope="session")
def dist(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The sdist and the wheel, built once a session: under xdist the first worker to ask builds
    them, under a lock, in the folder the run's workers share; the others wait and reuse them."""
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        return build_dist(tmp_path_factory.mktemp("dist"))
    shared = tmp_path_factory.getbasetemp().parent  # this run's, common to its workers
    with (shared / "jointangle-dist.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        return build_dist(shared / "jointangle-dist")


def system_python() -> str:
    """The system's Python 3.11+ (a user's; the checkout's may live where `nobody` cannot go)."""
    python = shutil.which("python3", path="/usr/local/bin:/usr/bin:/bin")
    assert python, "no python3 in /usr/local/bin, /usr/bin or /bin"
    version = subprocess.run([python, "-c", "import sys; print(sys.version_info >= (3, 11))"],
                             capture_output=True, text=True, check=True).stdout
    assert version.strip() == "True", f"{python} is older than 3.11"
    return python


def fresh_venv(where: Path, *install: str, env: dict[str, str] | None = None) -> Path:
    subprocess.run([system_python(), "-m", "venv", str(where)], check=True)
    res = subprocess.run([str(where / "bin" / "python"), "-m", "pip", "install", "-q", *install],
                         capture_output=True, text=True, check=False, env=env)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    return where / "bin"


def install_for_user(area: Path, dist: dict[str, Path]) -> tuple[Path, Path, dict[str, str]]:
    """The wheel in a fresh environment: (its bin/, the user's work folder, the user's
    environment)."""
    bin_dir = fresh_venv(area / "venv", str(dist["wheel"]))
    work = area / "work"
    work.mkdir()
    work.chmod(0o777)
    env = user_env(bin_dir, work)
    found = [c for c in COMPILERS if shutil.which(c, path=env["PATH"])]
    assert not found, f"the user's PATH must have no compiler: {found}"
    return bin_dir, work, env


def run(user: tuple[Path, Path, dict[str, str]], *argv: str, code: int = 0,
        extra_env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    bin_dir, work, env = user
    res = subprocess.run([*demote(), str(bin_dir / "jointangle"), *argv], cwd=work,
                         env={**env, **(extra_env or {})}, capture_output=True, text=True,
                         timeout=240, check=False)
    assert res.returncode == code, (argv, res.returncode, res.stdout[-2000:], res.stderr[-2000:])
    return res


def check_wheel_contents(dist: dict[str, Path]) -> None:
    import zipfile

    names = zipfile.ZipFile(dist["wheel"]).namelist()
    for part in WHEEL_PARTS:
        assert f"jointangle/_built/{part}" in names
    assert "jointangle/py.typed" in names and not [n for n in names if "__pycache__" in n]


def check_user_commands(user: tuple[Path, Path, dict[str, str]]) -> None:
    bin_dir, work, _ = user
    assert run(user, "--version").stdout.strip() == "jointangle 0.1.0"
    where = subprocess.run([str(bin_dir / "python"), "-c",
                            "import jointangle; print(jointangle.__file__)"],
                           capture_output=True, text=True, check=True, cwd=work).stdout
    assert where.startswith(str(bin_dir.parent)), where
    run(user, "simulate", "--scenario", "gravity-slow-periodic", "--seconds", "4", "--out",
        "data.csv", "--rig-out", "rig.toml")
    for name in ("array-ekf", "firmware"):
        run(user, "estimate", "--rig", "rig.toml", "--input", "data.csv", "--filter", name,
            "--out", f"{name}.csv")
        assert len((work / f"{name}.csv").read_text().splitlines()) > 300
    run(user, "plot", "--rig", "rig.toml", "--input", "data.csv", "--filters",
        "array-ekf,firmware", "--out", "fig.png")
    assert (work / "fig.png").stat().st_size > 10_000
    # a recording made by the wheel's native virtual board, replayed and verified
    run(user, "record", "--port", "sim://native?fast=1", "--seconds", "3", "--out", "run.jrec")
    doc = json.loads(run(user, "replay", "run.jrec", "--verify", "--verify-firmware",
                         "--json").stdout)
    assert doc["frames"] > 100 and doc["frames_lost"] == 0 and doc["crc_errors"] == 0
    assert doc["max_abs_dtheta_deg"] < 0.05
    rows = [json.loads(line) for line in run(user, "live", "--port", "sim://native?fast=1",
                                             "--json-lines", "--seconds", "3").stdout.splitlines()]
    assert len(rows) > 100 and all("theta_deg" in r for r in rows[-10:])
    parts = {f["message"].split(":")[0]: f for f in json.loads(
        run(user, "doctor", "--json", code=1).stdout)["findings"] if f["check"] == "parts"}
    for what in ("the firmware replay library", "the virtual device library",
                 "the native virtual board"):
        assert parts[what]["status"] == "ok" and str(bin_dir.parent) in parts[what]["message"]


def check_hidden_parts(user: tuple[Path, Path, dict[str, str]]) -> None:
    hide = {HIDE_ENV: "1"}
    run(user, "simulate", "--scenario", "gravity-ramp", "--seconds", "2", "--out", "h.csv",
        "--rig-out", "h.toml", extra_env=hide)
    run(user, "estimate", "--rig", "h.toml", "--input", "h.csv", "--filter", "array-ekf",
        "--out", "h_est.csv", extra_env=hide)
    for argv in (["estimate", "--rig", "h.toml", "--input", "h.csv", "--filter", "firmware",
                  "--out", "h_fw.csv"],
                 ["live", "--port", "sim://native", "--json-lines", "--seconds", "1"]):
        err = run(user, *argv, code=2, extra_env=hide).stderr
        assert err.count("\n") == 1 and "Traceback" not in err, err
        assert "install a jointangle wheel built for this platform" in err, err
        assert "cmake -S ." not in err  # no checkout here: no CMake advice


def test_user_install_from_the_wheel(dist: dict[str, Path], area: Path) -> None:
    check_wheel_contents(dist)
    user = install_for_user(area, dist)
    check_user_commands(user)  # the wheel, its parts, no compiler, not root
    check_hidden_parts(user)  # without the parts: pure Python works, the rest says what to get


def hide_simavr(area: Path) -> str:
    """CMAKE_IGNORE_PATH hiding libsimavr, libelf and sim_avr.h from the find calls the
    repository's project makes for them (firmware/CMakeLists.txt), as on a machine without
    them: a probe project makes the same calls, and the folders it finds them in are ignored
    until it finds none."""
    probe = area / "probe"
    probe.mkdir()
    (probe / "CMakeLists.txt").write_text(
        "cmake_minimum_required(VERSION 3.25)\nproject(probe LANGUAGES CXX)\n"
        "find_path(JA_SIMAVR_INCLUDE sim_avr.h PATH_SUFFIXES simavr)\n"
        "find_library(JA_SIMAVR_LIB simavr)\nfind_library(JA_ELF_LIB elf)\n"
        'message(STATUS "found: ${JA_SIMAVR_INCLUDE};${JA_SIMAVR_LIB};${JA_ELF_LIB}")\n')
    ignored: list[str] = []
    for _ in range(6):
        shutil.rmtree(probe / "build", ignore_errors=True)
        res = subprocess.run(["cmake", "-S", str(probe), "-B", str(probe / "build"),
                              f"-DCMAKE_IGNORE_PATH={';'.join(ignored)}"],
                             capture_output=True, text=True, check=True)
        found = [f for f in res.stdout.split("-- found: ")[1].splitlines()[0].split(";")
                 if f and not f.endswith("-NOTFOUND")]
        if not found:
            assert ignored, "simavr and libelf must be installed here, to be hidden"
            return ";".join(ignored)
        ignored += dict.fromkeys(f if Path(f).is_dir() else str(Path(f).parent) for f in found)
    raise AssertionError(f"simavr and libelf still found after ignoring {ignored}")


def test_the_wheels_cmake_skips_what_it_cannot_build(tmp_path: Path) -> None:
    """The wheel's CMake project (configured only: seconds) on a machine without simavr, libelf
    and Eigen: the configure succeeds, skipping the two parts that need Eigen in a STATUS line
    each, where the developer's configure of the repository stops at simavr."""
    ignore = hide_simavr(tmp_path)
    dev = subprocess.run(["cmake", "-S", str(REPO_ROOT), "-B", str(tmp_path / "dev"),
                          f"-DCMAKE_IGNORE_PATH={ignore}"], capture_output=True, text=True,
                         check=False)
    assert dev.returncode != 0 and "JA_SIMAVR_INCLUDE" in dev.stderr, dev.stderr[-2000:]
    res = subprocess.run(["cmake", "-S", str(REPO_ROOT / "packaging"), "-B",
                          str(tmp_path / "wheel"), f"-DCMAKE_IGNORE_PATH={ignore}",
                          "-DCMAKE_DISABLE_FIND_PACKAGE_Eigen3=ON"],
                         capture_output=True, text=True, check=False)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    assert "skipping ja_filter_replay and ja_native_board: Eigen 3.4 not found" in res.stdout
    assert "the wheel's compiled parts: ja_sim_devices\n" in res.stdout, res.stdout


def test_sdist_installs_the_parts_without_simavr(dist: dict[str, Path], area: Path) -> None:
    """A fresh environment, the sdist alone (its dependencies are the wheel test's business),
    on a machine where CMake cannot find simavr and libelf: pip builds the three parts with
    CMake (none needs them) and installs them into the package."""
    ignore = hide_simavr(area)
    bin_dir = fresh_venv(area / "venv-sdist", "--no-deps", "--no-cache-dir",
                         f"--config-settings=cmake.define.CMAKE_IGNORE_PATH={ignore}",
                         str(dist["sdist"]))
    site = next((bin_dir.parent / "lib").glob("python3*/site-packages"))
    for part in WHEEL_PARTS:
        assert (site / "jointangle" / "_built" / part).is_file(), part
    res = subprocess.run([str(site / "jointangle" / "_built" / "ja_native_board")],
                         capture_output=True, text=True, check=False)
    assert "usage: ja_native_board --rig RIG.toml" in res.stderr
    probe = ("import ctypes, sys; lib = ctypes.CDLL(sys.argv[1]); "
             "print(lib.ja_filter_raw_outputs_per_step())")
    out = subprocess.run([str(bin_dir / "python"), "-c", probe,
                          str(site / "jointangle" / "_built" / "libja_filter_replay.so")],
                         capture_output=True, text=True, check=True).stdout
    assert int(out) > 0


def test_sdist_without_a_compiler_installs_the_pure_python_host(dist: dict[str, Path],
                                                                area: Path) -> None:
    """The sdist where no C++ compiler works (CC and CXX a program that fails, as macOS's
    `c++` shim without the command-line tools; `false` is what CMake's compiler check gets):
    CMake fails, scikit-build-core builds again without it (pyproject.toml's override), and
    the pure-Python host installs and runs; a command needing a part says which in one line."""
    env = {**os.environ, "CC": shutil.which("false") or "false",
           "CXX": shutil.which("false") or "false"}
    bin_dir = fresh_venv(area / "venv", "--no-cache-dir", str(dist["sdist"]), env=env)
    site = next((bin_dir.parent / "lib").glob("python3*/site-packages"))
    assert not (site / "jointangle" / "_built").exists()
    wheel_meta = next(site.glob("jointangle-*.dist-info")) / "WHEEL"
    assert "Tag: py3-none-any" in wheel_meta.read_text()
    work = area / "work"
    work.mkdir()
    work.chmod(0o777)
    user = (bin_dir, work, user_env(bin_dir, work))
    assert run(user, "--version").stdout.strip() == "jointangle 0.1.0"
    run(user, "simulate", "--scenario", "gravity-slow-periodic", "--seconds", "4", "--out",
        "data.csv", "--rig-out", "rig.toml")
    run(user, "estimate", "--rig", "rig.toml", "--input", "data.csv", "--filter", "array-ekf",
        "--out", "est.csv")
    assert len((work / "est.csv").read_text().splitlines()) > 300
    err = run(user, "estimate", "--rig", "rig.toml", "--input", "data.csv", "--filter",
              "firmware", "--out", "fw.csv", code=2).stderr
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert "the firmware replay library (libja_filter_replay.so" in err, err
    assert "install a jointangle wheel built for this platform" in err, err
    parts = [f for f in json.loads(run(user, "doctor", "--json", code=1).stdout)["findings"]
             if f["check"] == "parts"]
    assert parts and all(f["status"] == "note" for f in parts), parts
