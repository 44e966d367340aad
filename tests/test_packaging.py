"""The wheel ships the asset folders and flapsim.core.assets finds them from an installed layout."""

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    out = tmp_path_factory.mktemp("wheel")
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-q", "-w",
                        str(out)], capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        pytest.fail(f"building the wheel failed: {r.stderr[-2000:]}")
    return next(out.glob("flapsim-*.whl"))


def test_wheel_contains_every_bundled_model(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    for folder in ("bird_mjcf", "swimmer_mjcf", "creatures"):
        for f in (ROOT / folder).rglob("*"):
            if f.is_file() and not f.name.startswith("."):
                rel = f.relative_to(ROOT).as_posix()
                assert f"flapsim/{rel}" in names, rel


def test_installed_layout_loads_every_bundled_model(wheel, tmp_path):
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    code = (
        "import mujoco, flapsim.core.assets as a\n"
        "from flapsim.core.loading import load_model\n"
        f"assert str(a.asset_dir('bird_mjcf')).startswith({str(site)!r}), a.asset_dir('bird_mjcf')\n"
        "n = 0\n"
        "for folder, paths in a.bundled_models().items():\n"
        "    for p in paths:\n"
        "        load_model(p); n += 1\n"
        "print(n)\n"
    )
    # run from an unrelated folder so nothing resolves through the working directory
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True,
                       env={"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin", "MUJOCO_GL": "egl"},
                       timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    expected = sum(len(list((ROOT / f).glob("*.xml"))) for f in ("bird_mjcf", "swimmer_mjcf",
                                                                  "creatures"))
    assert int(r.stdout.strip()) == expected


def test_the_constraints_pin_every_requirement_within_its_allowed_range():
    # constraints.txt (what CI and the README install) must pin each requirement of the
    # package and its test extra to a version pyproject.toml allows: a pin outside the range
    # would make `pip install -c constraints.txt -e ".[test]"` fail to resolve, a missing pin
    # would let that package float
    import tomllib

    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    root = Path(__file__).resolve().parents[1]
    project = tomllib.loads((root / "pyproject.toml").read_text())["project"]
    pins = {}
    for line in (root / "constraints.txt").read_text().splitlines():
        line = line.split("#")[0].strip()
        if line:
            name, version = line.split("==")
            pins[canonicalize_name(name)] = version
    assert "flapsim" not in pins
    for text in project["dependencies"] + project["optional-dependencies"]["test"]:
        req = Requirement(text)
        name = canonicalize_name(req.name)
        assert name in pins, f"{req.name} is not pinned in constraints.txt"
        assert req.specifier.contains(pins[name]), f"{req.name}=={pins[name]} is outside {req.specifier}"
