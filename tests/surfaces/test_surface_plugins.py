"""Surfaces as plug-ins: registry lookup, entry points, options, and unchanged arrays."""
from __future__ import annotations

import hashlib
import importlib
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

import psbench as ps
from psbench import registry
from psbench.registry import SurfaceSpec

REPO = Path(__file__).resolve().parents[2]
BUILTIN = {"semisphere", "semisphere_disc", "spheres", "sombrero", "sombrero1", "sombrero2",
           "sombrero3", "mozart", "penny", "cup", "vgroove", "cartridge", "cartridge_case"}

#: sha256 (first 32 hex digits) of height, object mask and normals bytes at size 48, taken
#: from the single-module surfaces.py before surfaces became plug-ins: the move changed
#: no value. (Values come from numpy's float64 maths; a platform whose libm rounds
#: sin/exp differently would change them in the last bit.)
HASHES_48 = {
    # the hemisphere's disc-only scene is the semisphere of before the ground plane
    "semisphere_disc": "4be4ba846dd1cbf94ead2f27e25935be",
    # the semisphere on its ground plane (the plane counts in the object mask)
    "semisphere": "faa0bb1010c9e2fdcf360252b9b2b3b0",
    "spheres": "ec92e4d3ca18530c139904009deb8c0c",
    "sombrero": "fb57dc44b32dbb1f001a9990f3ae6b07",
    "sombrero1": "c25b4da841edc60f4922ace8ef8e093d",
    "sombrero2": "fb57dc44b32dbb1f001a9990f3ae6b07",
    "sombrero3": "34f26d32a55b9655a10f170f65e4d3d5",
    "mozart": "835ffc4fc7ad1976c9a69b7b6d88af48",
    "penny": "7b98804a25126e78e09c429fa003d0a6",
}


def _digest(s):
    h = hashlib.sha256()
    for a in (s.height, s.object_mask, s.normals):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:32]


@pytest.mark.parametrize("name", sorted(HASHES_48))
def test_surfaces_bit_identical_to_before(name):
    assert _digest(ps.make_surface(name, size=48)) == HASHES_48[name]


def test_surfaces_listed_from_the_registry():
    assert set(ps.SURFACES) == BUILTIN == set(ps.surfaces.SURFACES)
    assert set(registry.names("surfaces")) == BUILTIN
    assert registry.get("surfaces", "sombrero") is registry.get("surfaces", "sombrero2")


def test_entry_points_declared_for_every_builtin_module():
    tomllib = pytest.importorskip("tomllib")  # Python >= 3.11
    doc = tomllib.loads((REPO / "pyproject.toml").read_text())
    eps = doc["project"]["entry-points"]["psbench.surfaces"]
    mods = {p.stem for p in (REPO / "psbench" / "surfaces").glob("[!_]*.py")}
    # cartridge is forensic's own surface, registered from its package (forensic/surface.py)
    assert set(eps) == mods | {"cartridge"}
    assert eps["cartridge"] == "psbench.forensic.surface:SURFACE"
    for name, value in eps.items():
        mod, attr = value.split(":")
        spec = getattr(importlib.import_module(mod), attr)
        assert isinstance(spec, SurfaceSpec) and spec.name == name and spec.help


def test_convention_fallback_without_metadata(monkeypatch):
    """A source tree without installed entry points finds the same surfaces."""
    real = metadata.entry_points

    def no_surfaces(**kw):
        return [] if kw.get("group") == "psbench.surfaces" else real(**kw)

    monkeypatch.setattr(registry.metadata, "entry_points", no_surfaces)
    registry.reload("surfaces")
    try:
        assert set(ps.SURFACES) == BUILTIN
        assert _digest(ps.make_surface("penny", size=48)) == HASHES_48["penny"]
    finally:
        monkeypatch.undo()
        registry.reload("surfaces")


def test_alias_and_case_keep_the_asked_name():
    assert ps.make_surface("sombrero", size=32).name == "sombrero"
    assert ps.make_surface("sombrero2", size=32).name == "sombrero2"
    assert ps.make_surface("SOMBRERO", size=32).name == "sombrero"
    assert ps.make_surface("Penny", size=32).name == "penny"


def _bump(size, *, height=1.0, pixel_size=1.0):
    z = np.zeros((size, size))
    z[size // 4: 3 * size // 4, size // 4: 3 * size // 4] = height / pixel_size
    return ps.surface_from_height(z, name="bump")


@pytest.fixture
def bump():
    spec = registry.register("surfaces", SurfaceSpec("bump", _bump, help="a box",
                                                      aliases=("box",)))
    yield spec
    registry.unregister("surfaces", "bump")


def test_plugin_surface_gets_its_options(bump):
    assert "bump" in ps.SURFACES and "box" in ps.SURFACES
    s = ps.make_surface("bump", size=32, height=6.0, pixel_size=2.0)
    assert s.height.max() == pytest.approx(3.0) and s.name == "bump"
    assert ps.make_surface("box", size=32).name == "box"
    with pytest.raises(ps.PsbenchError, match="takes no option 'gun'; its options: height, "
                                              "pixel_size"):
        ps.make_surface("bump", size=32, gun=3)


def test_plugin_surface_in_the_preview_command(bump, tmp_path, capsys):
    from psbench.surfaces import main
    assert main(["--out", str(tmp_path), "--size", "32", "--names", "bump"]) == 0
    assert (tmp_path / "bump.png").is_file()


def test_plugin_must_return_a_surface():
    registry.register("surfaces", SurfaceSpec("broken", lambda size: np.zeros((size, size))))
    try:
        with pytest.raises(ps.PsbenchError, match="returned ndarray, expected psbench.Surface"):
            ps.make_surface("broken", size=32)
    finally:
        registry.unregister("surfaces", "broken")


@pytest.mark.parametrize("call, match", [
    (lambda: ps.make_surface("teapot"), r"name='teapot' is not known; valid choices: cartridge, cartridge_case, cup, mozart, "
                                        r"penny, semisphere"),
    (lambda: ps.make_surface(3), "name must be a surface name"),
    (lambda: ps.make_surface("penny", size=32, gun=3), "takes no option 'gun'; its options: none"),
    (lambda: ps.make_surface("penny", size=8.5), "size must be an integer"),
])
def test_bad_names_and_options(call, match):
    with pytest.raises(ps.PsbenchError, match=match):
        call()


def test_surface_is_read_only_and_pickles():
    import pickle

    s = ps.make_surface("semisphere", size=24)
    with pytest.raises(AttributeError):
        s.name = "x"
    with pytest.raises(ValueError):
        s.height[0, 0] = 1.0
    t = pickle.loads(pickle.dumps(s))
    assert _digest(t) == _digest(s) and t.name == s.name


def test_no_surface_module_imported_before_use():
    code = ("import sys, psbench; "
            "print(sorted(m for m in sys.modules if m.startswith('psbench.surfaces.')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "psbench.surfaces.penny" not in out and "psbench.surfaces.mozart" not in out
