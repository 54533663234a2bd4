"""The package builds, installs and runs like a catkin package, on /usr/bin/python3 whatever python3 is first on PATH."""
import ctypes
import json
import os
import pathlib
import re
import shutil
import subprocess
import textwrap

import pytest
from graph_helpers import free_port

PROJECT = pathlib.Path(__file__).resolve().parents[2]
ROS_PYTHON = "/usr/bin/python3"

pytestmark = pytest.mark.skipif(shutil.which("catkin_make") is None or shutil.which("rosrun") is None,
                                reason="catkin_make/rosrun missing: run `make test`, which installs them")


@pytest.fixture
def foreign_python(tmp_path):
    """A directory whose python3 refuses to run, to put first on PATH (as pyenv, a venv or conda would)."""
    bin_dir = tmp_path / "foreign_bin"
    bin_dir.mkdir()
    fake = bin_dir / "python3"
    fake.write_text("#!/bin/sh\necho 'foreign python3 was used' >&2\nexit 97\n")
    fake.chmod(0o755)
    return bin_dir


def clean_ros_env(path_first):
    """The environment minus every workspace's variables, with path_first in front of PATH."""
    env = {k: v for k, v in os.environ.items()
           if not k.startswith("ROS") and k not in ("CMAKE_PREFIX_PATH", "PYTHONPATH", "LD_LIBRARY_PATH",
                                                    "PKG_CONFIG_PATH")}
    env["PATH"] = f"{path_first}:{env['PATH']}"
    return env


def run_in(setup_bash, script, env, cwd, timeout=120):
    return subprocess.run(["bash", "-c", f"source {setup_bash} && {script}"], env=env, cwd=cwd,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=timeout)


def test_rosrun_and_roslaunch_with_foreign_python_first(tmp_path, foreign_python):
    """rosrun and roslaunch run the nodes on ROS's Python while another python3 comes first on PATH."""
    devel_setup = os.environ.get("EXAMPLE_PCL_DEVEL_SETUP", str(PROJECT / "build/ws/devel/setup.bash"))
    if not os.path.isfile(devel_setup):
        pytest.skip(f"{devel_setup} missing: build with `make build` first")
    env = clean_ros_env(foreign_python)
    assert subprocess.run(["python3", "-c", "pass"], env=env).returncode == 97  # the trap is armed

    scene = tmp_path / "scene.pcd"
    proc = run_in(devel_setup, f"rosrun example_pcl make_scene {scene} --no-noise --format binary", env, tmp_path)
    assert proc.returncode == 0 and scene.is_file(), proc.stdout
    assert "foreign python3" not in proc.stdout

    env["ROS_MASTER_URI"] = f"http://127.0.0.1:{free_port()}"  # roslaunch starts its own master there
    env["ROS_HOME"] = str(tmp_path / "ros_home")
    out = tmp_path / "snapshot.pcd"
    proc = run_in(devel_setup, f"roslaunch example_pcl pcd_save.launch file:={scene} out:={out} format:=binary rate:=5",
                  env, tmp_path, timeout=120)
    assert out.is_file(), proc.stdout[-4000:]
    assert "foreign python3" not in proc.stdout


def copy_package(dest):
    """The working tree's package files (no build outputs, no git metadata) copied to dest."""
    shutil.copytree(PROJECT, dest, ignore=shutil.ignore_patterns("build", ".git", "__pycache__", ".pytest_cache"))


def test_fresh_workspace_devel_and_install_spaces(tmp_path, foreign_python):
    """In a user's fresh catkin workspace, catkin_make and catkin_make install build it, without a
    warning from our CMake or C++; nodes run from devel and install."""
    ws = tmp_path / "catkin_ws"
    copy_package(ws / "src" / "example_pcl")
    env = dict(clean_ros_env(foreign_python), PWD=str(ws))  # catkin_make takes the workspace from $PWD
    build = subprocess.run(["catkin_make", f"-DPYTHON_EXECUTABLE={ROS_PYTHON}", "-DCMAKE_EXPORT_COMPILE_COMMANDS=ON",
                            "install"], cwd=ws, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                           timeout=900)
    assert build.returncode == 0, build.stdout[-6000:]
    # Every C++ file of ours is compiled with -Wall -Wextra, and the compiler, linker and CMake warn
    # about nothing ("file:line:col: warning: ...", "ld: warning: ...", "CMake Warning"). PCL's,
    # Eigen's and rviz's headers are SYSTEM includes, so their warnings are not shown. Not ours:
    # PCL's config notice "** WARNING ** io features related to pcap will be disabled", and
    # setuptools' "setup.py install is deprecated" / "byte-compiling is disabled" when catkin installs
    # the Python package.
    compiled = [c for c in json.loads((ws / "build/compile_commands.json").read_text()) if "/cpp/" in c["file"]]
    assert len(compiled) == len(list((PROJECT / "cpp").rglob("*.cpp")))
    assert all("-Wall" in c["command"] and "-Wextra" in c["command"] for c in compiled), compiled
    warnings = [line for line in build.stdout.splitlines() if re.search(r": warning: |^CMake Warning", line)]
    assert not warnings, "\n".join(warnings)
    assert not (ws / "devel/lib/example_pcl/bench").exists()  # benchmark programs only when asked (make bench)

    check = textwrap.dedent(f"""\
        set -e
        rospack find example_pcl
        rosrun example_pcl make_scene {tmp_path}/SPACE.pcd --no-noise --format binary
        {ROS_PYTHON} -c 'import example_pcl._native as n, example_pcl.srv as s; print(n.__file__); print(s.__file__)'
        echo "rviz plugins: $(rospack plugins --attrib=plugin rviz | grep '^example_pcl ')"
        """)
    for space in ("devel", "install"):
        proc = run_in(ws / space / "setup.bash", check.replace("SPACE", space), env, tmp_path)
        assert proc.returncode == 0, proc.stdout
        lines = proc.stdout.splitlines()
        assert (tmp_path / f"{space}.pcd").is_file()
        native_path = next(line for line in lines if "_native" in line)
        assert native_path.startswith(str(ws / space)), native_path
        # rviz finds the Publish Selection tool through the exported plugin_description.xml, and its
        # library (linked against rviz's default plugins, where SelectionTool lives) loads.
        description = pathlib.Path(next(line for line in lines if line.startswith("rviz plugins:")).split()[-1])
        assert description.is_file(), proc.stdout
        library = ws / space / "lib" / "libexample_pcl_rviz_tools.so"
        assert 'path="lib/libexample_pcl_rviz_tools"' in description.read_text()
        ctypes.CDLL(str(library))
    installed = ws / "install" / "lib" / "example_pcl"
    for script in ("find_can", "pcd_save", "pcd_publisher", "make_scene"):
        if (PROJECT / "scripts" / script).exists():
            assert (installed / script).read_text().startswith(f"#!{ROS_PYTHON}"), script
    assert (ws / "install" / "share" / "example_pcl" / "data" / "test_pcd.pcd").is_file()
    assert (ws / "install" / "share" / "example_pcl" / "launch" / "pcd_save.launch").is_file()

    # catkin_make run_tests runs the registered suites (here one unit test, through PYTEST_ADDOPTS) and
    # catkin_test_results finds their results; every rostest launch file is registered.
    tests = subprocess.run(["catkin_make", "run_tests_example_pcl_pytest_unit"], cwd=ws, timeout=600,
                           env=dict(env, PYTEST_ADDOPTS="-k test_version_is_package_xml"),
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert tests.returncode == 0, tests.stdout[-6000:]
    results = subprocess.run(["catkin_test_results", "build/test_results"], cwd=ws, env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert results.returncode == 0 and "1 tests, 0 errors, 0 failures" in results.stdout, results.stdout
    targets = subprocess.run(["make", "-C", "build", "help"], cwd=ws, env=env, stdout=subprocess.PIPE, text=True).stdout
    for launch in (PROJECT / "test/integration").glob("*.test"):
        assert f"run_tests_example_pcl_rostest_test_integration_{launch.name}" in targets, launch.name


def test_every_script_is_installed():
    """Every file in scripts/ is listed in CMakeLists.txt's catkin_install_python (the list is written out for catkin_lint)."""
    cmake = (PROJECT / "CMakeLists.txt").read_text()
    listed = re.search(r"catkin_install_python\(PROGRAMS(.*?)DESTINATION", cmake, re.S).group(1).split()
    assert sorted(listed) == sorted(f"scripts/{p.name}" for p in (PROJECT / "scripts").iterdir() if p.is_file())


@pytest.mark.skipif(shutil.which("catkin_lint") is None, reason="catkin_lint missing: apt-get install catkin-lint")
def test_catkin_lint_finds_nothing(tmp_path):
    """catkin_lint, notices included (-W2), reports no problem in the package."""
    checkout = tmp_path / "example_pcl"  # catkin_lint wants the package's directory named after it
    checkout.symlink_to(PROJECT)
    proc = subprocess.run(["catkin_lint", "-W2", "--strict", str(checkout)], stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True, timeout=120)
    assert proc.returncode == 0 and "found 0 problems" in proc.stdout, proc.stdout
