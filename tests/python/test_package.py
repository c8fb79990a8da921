"""The hpcm package as users install and read it: a docstring and a stub for every public name,
`cmake --install` into a temporary prefix, `pip install .` into a temporary virtual environment
and into a temporary root laid out like the system Python's; each import is done from another
folder, without the build tree on the path. Nothing is installed outside pytest's tmp_path: the
pip tests reuse this build tree (HPCM_BUILD_DIR) instead of building the module again."""
import ast
import inspect
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import hpcm

SOURCE_DIR = Path(os.environ.get("HPCM_SOURCE_DIR", Path(__file__).resolve().parents[2]))
BINARY_DIR = os.environ.get("HPCM_BINARY_DIR")
STUBS = SOURCE_DIR / "python" / "hpcm" / "__init__.pyi"
PYTHON = sys.executable

# pybind11 puts "name(args) -> result" lines (numbered when overloaded) before the docstring.
_SIGNATURE_LINE = re.compile(r"^\s*(\d+\.\s+)?[A-Za-z_][\w.]*\(.*\)(\s*->\s*.+)?\s*$")


def project_version():
    text = (SOURCE_DIR / "CMakeLists.txt").read_text()
    return re.search(r"project\(\s*hpcm\s+VERSION\s+([0-9.]+)", text).group(1)


def _own_doc(obj):
    """The docstring text beyond pybind11's generated signature lines ('' when none)."""
    doc = inspect.getdoc(obj) or ""
    lines = [ln for ln in doc.splitlines()
             if ln.strip() and ln.strip() != "Overloaded function." and not _SIGNATURE_LINE.match(ln)]
    return "\n".join(lines).strip()


def _is_code(obj):
    return inspect.isclass(obj) or callable(obj) or isinstance(obj, property)


def _public(names):
    return sorted(n for n in names if not n.startswith("_"))


def _class_members(cls):
    """Public members defined by the class itself (inherited object/pybind11 members excluded);
    static methods unwrapped (a staticmethod object shows the docstring of `staticmethod`)."""
    return {n: v.__func__ if isinstance(v, (staticmethod, classmethod)) else v
            for n, v in vars(cls).items() if not n.startswith("_")}


def _module_public():
    return {n: getattr(hpcm, n) for n in _public(dir(hpcm)) if not inspect.ismodule(getattr(hpcm, n))}


def _stub_names():
    """Top-level names of the stubs and, per class, the names of its members."""
    tree = ast.parse(STUBS.read_text(), filename=str(STUBS))
    top, members = set(), {}

    def names_in(body):
        found = set()
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                found.add(node.name)
            elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
                found.add(node.target.id)
            elif isinstance(node, ast.Assign):
                found.update(t.id for t in node.targets if isinstance(t, ast.Name))
            elif isinstance(node, ast.ImportFrom) and node.level > 0:  # re-exports, not typing's names
                found.update(a.asname or a.name for a in node.names)
        return found

    top = names_in(tree.body)
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            members[node.name] = names_in(node.body)
    return top, members


def test_every_public_name_has_a_docstring():
    missing = []
    for name, obj in _module_public().items():
        if _is_code(obj) and not _own_doc(obj):
            missing.append(f"hpcm.{name}")
        if inspect.isclass(obj):
            for member, value in _class_members(obj).items():
                if _is_code(value) and not isinstance(value, obj) and not _own_doc(value):
                    missing.append(f"hpcm.{name}.{member}")
    assert not missing, f"{len(missing)} public names without a docstring: {', '.join(missing)}"


def test_the_stubs_name_every_public_name():
    top, members = _stub_names()
    missing = [f"hpcm.{n}" for n in _module_public() if n not in top]
    for name, obj in _module_public().items():
        if inspect.isclass(obj):
            missing += [f"hpcm.{name}.{m}" for m in _class_members(obj) if m not in members.get(name, set())]
    assert not missing, f"{STUBS} lacks {len(missing)} public names: {', '.join(missing)}"
    assert "__version__" in top


def test_the_stubs_name_nothing_that_does_not_exist():
    if not hpcm.has_io:
        pytest.skip("built without ITK: the file functions the stubs describe are absent")
    top, members = _stub_names()
    stale = [f"hpcm.{n}" for n in _public(top) if not hasattr(hpcm, n)]
    for cls, names in members.items():
        if hasattr(hpcm, cls):
            stale += [f"hpcm.{cls}.{m}" for m in _public(names) if not hasattr(getattr(hpcm, cls), m)]
    assert not stale, f"{STUBS} describes names the module does not have: {', '.join(stale)}"


def test_version_is_the_cmake_project_version():
    assert hpcm.__version__ == project_version()


@pytest.mark.skipif(not os.environ.get("HPCM_BINARY_DIR"), reason="HPCM_BINARY_DIR (the CMake build tree) not given")
def test_the_cxx_version_header_has_the_same_version():
    # <hpcm/version.hpp> is what the CLI's --version reads.
    header = Path(os.environ["HPCM_BINARY_DIR"], "generated", "include", "hpcm", "version.hpp").read_text()
    assert f'#define HPCM_VERSION_STRING "{project_version()}"' in header
    major, minor, patch = (project_version().split(".") + ["0", "0"])[:3]
    assert f"#define HPCM_VERSION_MAJOR {major}\n" in header and f"#define HPCM_VERSION_PATCH {patch}\n" in header


# ---- installing ------------------------------------------------------------------------------


def _clean_env(**extra):
    """The environment without the build tree's package on the path."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env.update(extra)
    return env


def _import_from_elsewhere(python, tmp_path, **env):
    """Imports hpcm in a fresh interpreter from an unrelated folder: (version, file)."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir(exist_ok=True)
    out = subprocess.run([str(python), "-c", "import hpcm; print(hpcm.__version__); print(hpcm.__file__)"],
                         cwd=elsewhere, env=_clean_env(**env), capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    version, file = out.stdout.split()
    return version, Path(file)


def _sys_path(python):
    out = subprocess.run([str(python), "-c", "import sys; print('\\n'.join(sys.path))"],
                         env=_clean_env(), capture_output=True, text=True, check=True, timeout=60)
    return [Path(p) for p in out.stdout.splitlines() if p]


def _source_copy(tmp_path):
    """The source tree without build folders (pip builds in the tree it is given)."""
    copy = tmp_path / "src"
    shutil.copytree(SOURCE_DIR, copy, ignore=shutil.ignore_patterns(
        "build*", ".git", "__pycache__", "*.egg-info", "out", ".deps", ".whl"))
    return copy


def _run_pip_install(python, tmp_path, build_dir, *args):
    return subprocess.run([str(python), "-m", "pip", "install", "--no-build-isolation", "--no-index",
                           "--disable-pip-version-check", "--no-cache-dir", *args, str(_source_copy(tmp_path))],
                          cwd=tmp_path, env=_clean_env(HPCM_BUILD_DIR=str(build_dir)),
                          capture_output=True, text=True, timeout=600)


def _pip_install(python, tmp_path, *args):
    out = _run_pip_install(python, tmp_path, BINARY_DIR, *args)
    assert out.returncode == 0, out.stdout[-4000:] + out.stderr[-4000:]


def _assert_complete_package(package_dir):
    names = {p.name for p in package_dir.iterdir()}
    assert {"__init__.py", "__init__.pyi", "py.typed", "cohort.py", "cohort_report.py"} <= names, names
    assert any(n.startswith("_hpcm") and n.endswith(".so") for n in names), names


needs_build_dir = pytest.mark.skipif(not BINARY_DIR, reason="HPCM_BINARY_DIR (the CMake build tree) not given")


@needs_build_dir
def test_cmake_install_puts_the_package_where_python_finds_it(tmp_path):
    prefix = tmp_path / "prefix"
    subprocess.run(["cmake", "--install", BINARY_DIR, "--prefix", str(prefix), "--component", "python"],
                   check=True, capture_output=True, timeout=120)
    install_dir = os.environ["HPCM_PYTHON_INSTALL_DIR"]
    _assert_complete_package(prefix / install_dir / "hpcm")
    version, file = _import_from_elsewhere(PYTHON, tmp_path, PYTHONPATH=str(prefix / install_dir))
    assert version == project_version()
    assert file.is_relative_to(prefix)
    # The default prefix must be one this Python searches without PYTHONPATH.
    if os.environ.get("HPCM_INSTALL_PREFIX") == "/usr/local":
        assert Path("/usr/local", install_dir) in _sys_path(PYTHON)


@needs_build_dir
def test_pip_installs_into_a_virtual_environment(tmp_path):
    venv = tmp_path / "venv"
    subprocess.run([PYTHON, "-m", "venv", "--system-site-packages", str(venv)], check=True, timeout=120)
    python = venv / "bin" / "python"
    _pip_install(python, tmp_path)
    version, file = _import_from_elsewhere(python, tmp_path)
    assert version == project_version()
    assert file.is_relative_to(venv)
    _assert_complete_package(file.parent)
    meta = subprocess.run([str(python), "-c", "import importlib.metadata as m; print(m.version('hpcm'))"],
                          env=_clean_env(), capture_output=True, text=True, check=True, timeout=60)
    assert meta.stdout.strip() == project_version()


@needs_build_dir
def test_pip_installs_where_the_system_python_finds_it(tmp_path):
    # --root: the layout `pip install .` gives this interpreter, under a temporary folder.
    root = tmp_path / "root"
    _pip_install(PYTHON, tmp_path, "--root", str(root))
    inits = list(root.rglob("hpcm/__init__.py"))
    assert len(inits) == 1, inits
    package_dir = inits[0].parent
    _assert_complete_package(package_dir)
    site_dir = Path("/", package_dir.parent.relative_to(root))
    assert site_dir in _sys_path(PYTHON), f"pip would install into {site_dir}, which {PYTHON} does not search"
    version, file = _import_from_elsewhere(PYTHON, tmp_path, PYTHONPATH=str(package_dir.parent))
    assert version == project_version()
    assert file.is_relative_to(root)


def test_pip_refuses_a_build_dir_that_is_not_configured(tmp_path):
    empty = tmp_path / "not-a-build"
    empty.mkdir()
    out = _run_pip_install(PYTHON, tmp_path, empty, "--no-deps", "--target", str(tmp_path / "target"))
    assert out.returncode != 0
    assert f"HPCM_BUILD_DIR={empty}: not a configured CMake build folder" in out.stdout + out.stderr
    assert not (tmp_path / "target" / "hpcm").exists()
