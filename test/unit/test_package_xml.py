"""package.xml declares, by rosdep key, every module the code imports, and tools/debian-packages.txt installs it."""
import ast
import pathlib
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest

PROJECT = pathlib.Path(__file__).resolve().parents[2]
# Installed code: what it imports must be there at run time (depend or exec_depend).
RUN_DIRS = ("src", "scripts")
# Tests, benchmarks and developer tools: test_depend is enough.
TEST_DIRS = ("test", "bench", "tools")
RUN_TYPES = {"depend", "exec_depend"}
TEST_TYPES = RUN_TYPES | {"test_depend"}

# Imported modules that are not ROS packages, and their rosdep keys. A ROS package's key is its name.
ROSDEP_KEYS = {
    "PIL": "python3-pil",
    # A ROS package, but Debian ships only its Python module (python3-diagnostic-updater), which rospkg cannot find.
    "diagnostic_updater": "diagnostic_updater",
    "hypothesis": "python3-hypothesis",
    "matplotlib": "python3-matplotlib",
    "numpy": "python3-numpy",
    "pytest": "python3-pytest",
    "rospkg": "python3-rospkg",
    "scipy": "python3-scipy",
    "yaml": "python3-yaml",
}
# Imported on purpose without a package.xml entry, and why.
UNDECLARED = {
    "open3d": "benchmarks only: tools/bench_env.sh installs it from PyPI into the bench venv (not in Debian)",
}


def python_files(top):
    """The Python files under top: *.py and extensionless scripts with a python shebang."""
    for path in sorted((PROJECT / top).rglob("*")):
        if not path.is_file() or "__pycache__" in path.parts:
            continue
        if path.suffix == ".py" or (not path.suffix and path.read_bytes()[:64].startswith(b"#!")
                                    and b"python" in path.read_bytes().split(b"\n", 1)[0]):
            yield path


def imported_modules(path):
    """The top-level names of the absolute imports in one file."""
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            yield from (alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.module.split(".")[0]


def local_modules():
    """The project's own modules: the packages in src/ and the helper modules and packages beside the tests,
    benchmarks and tools (imported through their directory on sys.path)."""
    names = {p.name for p in (PROJECT / "src").iterdir() if (p / "__init__.py").is_file()}
    for top in TEST_DIRS:
        for path in (PROJECT / top).rglob("*"):
            if path.suffix == ".py":
                names.add(path.stem)
            elif path.is_dir() and (path / "__init__.py").is_file():
                names.add(path.name)
    return names


def third_party_imports(dirs):
    """{module: [file, ...]} of the imports in dirs that are neither the standard library nor the project's."""
    local = local_modules()
    found = {}
    for top in dirs:
        for path in python_files(top):
            for module in imported_modules(path):
                if module not in sys.stdlib_module_names and module not in local and module != "__future__":
                    found.setdefault(module, []).append(str(path.relative_to(PROJECT)))
    return found


def declared(types):
    """The rosdep keys package.xml declares with one of the given dependency types."""
    root = ET.parse(PROJECT / "package.xml").getroot()
    return {element.text.strip() for element in root if element.tag in types}


def rosdep_key(module):
    """The rosdep key of the package providing module, or None when nobody knows it."""
    if module in ROSDEP_KEYS:
        return ROSDEP_KEYS[module]
    import rospkg
    try:
        rospkg.RosPack().get_path(module)
    except rospkg.ResourceNotFound:
        return None
    return module


def undeclared(dirs, types):
    """Lines naming each import in dirs whose rosdep key package.xml lacks among types."""
    keys = declared(types)
    problems = []
    for module, files in sorted(third_party_imports(dirs).items()):
        if module in UNDECLARED:
            continue
        key = rosdep_key(module)
        if key is None:
            problems.append(f"{module} (imported by {files[0]}): no rosdep key known; add it to ROSDEP_KEYS")
        elif key not in keys:
            tag = sorted(types)[-1]
            problems.append(f"{module} (imported by {files[0]}): package.xml needs <{tag}>{key}</{tag}> "
                            f"(or one of {', '.join(sorted(types))})")
    return problems


def test_installed_code_imports_are_run_dependencies():
    """Every module src/ and scripts/ import is a depend or exec_depend of package.xml."""
    assert undeclared(RUN_DIRS, RUN_TYPES) == []


def test_test_bench_and_tool_imports_are_declared():
    """Every module test/, bench/ and tools/ import is declared (test_depend at least) in package.xml."""
    assert undeclared(TEST_DIRS, TEST_TYPES) == []


def test_a_missing_declaration_is_named(monkeypatch):
    """The check fails, naming module and key, when package.xml lacks a dependency (here rospy and numpy)."""
    real = declared
    monkeypatch.setitem(globals(), "declared", lambda types: real(types) - {"rospy", "python3-numpy"})
    problems = undeclared(RUN_DIRS, RUN_TYPES)
    assert any(p.startswith("rospy ") and ">rospy<" in p for p in problems), problems
    assert any(p.startswith("numpy ") and ">python3-numpy<" in p for p in problems), problems


def test_a_test_only_declaration_does_not_satisfy_installed_code(monkeypatch):
    """A module src/ imports but package.xml lists only as test_depend is reported."""
    real = declared
    monkeypatch.setitem(globals(), "declared",
                        lambda types: real(types) - {"python3-numpy"} if "test_depend" not in types else real(types))
    assert any(p.startswith("numpy ") for p in undeclared(RUN_DIRS, RUN_TYPES))


def test_local_and_standard_modules_are_not_dependencies():
    """The project's own modules, the test helpers and the standard library never count as imports to declare."""
    found = third_party_imports(RUN_DIRS + TEST_DIRS)
    for module in ("example_pcl", "graph_helpers", "fuzz", "common", "netns_graph", "os", "subprocess"):
        assert module not in found
    assert "rospy" in found and "numpy" in found  # the scan sees real imports


@pytest.mark.skipif(shutil.which("dpkg-query") is None, reason="dpkg-query missing: not a Debian system")
def test_debian_packages_list_installs_every_import():
    """tools/debian-packages.txt names the Debian package providing each imported module, so `make` installs it."""
    import importlib.util
    listed = {line.strip() for line in (PROJECT / "tools/debian-packages.txt").read_text().splitlines()
              if line.strip() and not line.lstrip().startswith("#")}
    missing = []
    for module, files in sorted(third_party_imports(RUN_DIRS + TEST_DIRS).items()):
        if module in UNDECLARED:
            continue
        spec = importlib.util.find_spec(module)
        assert spec is not None, f"{module} (imported by {files[0]}) is not installed"
        origin = spec.origin if spec.origin not in (None, "namespace") else next(iter(spec.submodule_search_locations))
        owner = subprocess.run(["dpkg-query", "-S", str(pathlib.Path(origin).resolve())], capture_output=True,
                               text=True)
        if owner.returncode != 0:
            continue  # not from a Debian package (e.g. the devel space): nothing to install
        package = owner.stdout.split(":", 1)[0]
        if package not in listed:
            missing.append(f"{module} (imported by {files[0]}): {package}")
    assert missing == []
