"""Masks and methods from outside psbench: registered at run time and through a real
entry point, then used by ps.solve like the built-ins."""
import sys
import textwrap
from dataclasses import dataclass

import numpy as np
import pytest

import psbench as ps
from psbench import registry
from psbench._shared.checks import PsbenchError
from psbench.solve import MASKS, METHODS
from psbench.solve.base import Fit, Options, check_number
from psbench.solve.thresholds import resolve_thresholds


# ------------------------------------------------------------- a tiny mask
def _dark(images, ctx):
    """Image stage: mask observations below t_dark of the mean dynamic range."""
    return images >= np.float32(ctx.thresholds["t_dark"] * ctx.scale)


DARK = registry.Mask("Dark", "image", _dark, ranges=True,
                     thresholds=(registry.Threshold("t_dark", 0.1, (0.0, 1.0)),),
                     help="observations darker than t_dark of the range")


def _far(images, b, ctx):
    """Local normal stage: mask residuals above t_far of the range (a symmetric Hi-CS)."""
    r = images - np.asarray(ctx.S32 @ b.T)
    return np.abs(r) <= np.float32(ctx.thresholds["t_far"] * ctx.scale)


FAR = registry.Mask("Far", "normal", _far, ranges=True,
                    thresholds=(registry.Threshold("t_far", (0.2, 0.1), (0.0, 5.0),
                                                   counts=(4, 12)),))


# ------------------------------------------------------------- a tiny method
@dataclass
class ShrinkOptions(Options):
    """Options of "mymethod".

    Parameters
    ----------
    shrink : float
        Factor on the masked least-squares albedo, in (0, 1].
    """

    shrink: float = 0.5

    def __post_init__(self):
        super().__post_init__()
        check_number(self.shrink, "shrink", lo=0, hi=1, lo_open=True)


def _shrink(problem, options):
    return Fit(b=problem.start() * np.float32(options.shrink),
               iterations=np.full(problem.images.shape[1:], 2),  # a per-pixel count
               info={"kept": int(problem.valid.sum())})


SHRINK = registry.Method("mymethod", _shrink, options=ShrinkOptions,
                         help="masked LS with a shrunk albedo")


@pytest.fixture(scope="module")
def scene():
    surf = ps.make_surface("sombrero", size=48)
    lay = ps.layout("45x8")
    return surf, lay, ps.render(surf, lay, noise=0.02, seed=1)


@pytest.fixture
def plugins():
    for group, spec in (("masks", DARK), ("masks", FAR), ("methods", SHRINK)):
        registry.register(group, spec)
    yield
    for group, name in (("masks", "Dark"), ("masks", "Far"), ("methods", "mymethod")):
        registry.unregister(group, name)


def test_runtime_mask_combines_with_builtins(scene, plugins):
    surf, lay, sc = scene
    res = ps.solve(sc.images, lay, mask="Th-dark", object_mask=surf.object_mask, max_iter=0)
    th = ps.solve(sc.images, lay, mask="Th", object_mask=surf.object_mask, max_iter=0)
    assert res.mask == "Th-Dark"
    assert res.thresholds["t_dark"] == 0.1
    dr = np.mean([np.ptp(im) for im in sc.images])
    dark = sc.images >= np.float32(0.1 * dr)
    want = th.valid & dark
    ok = want.sum(0) >= 3  # elsewhere Eq. 3.1 completes to three observations
    assert np.array_equal(res.valid[:, ok & surf.object_mask], want[:, ok & surf.object_mask])
    assert not np.array_equal(res.valid, th.valid)
    # its threshold is overridable and validated like Table 5.2's
    more = ps.solve(sc.images, lay, mask="Dark", thresholds={"t_dark": 0.2}, max_iter=0)
    assert (~more.valid).sum() > (~ps.solve(sc.images, lay, mask="Dark").valid).sum()
    with pytest.raises(PsbenchError, match=r"t_dark.*out of range"):
        ps.solve(sc.images, lay, mask="Dark", thresholds={"t_dark": 2.0})
    assert "Dark" in __import__("psbench.solve", fromlist=["MASKS"]).MASKS


def test_runtime_normal_mask_iterates(scene, plugins):
    surf, lay, sc = scene
    res = ps.solve(sc.images, lay, mask="Far-Sh", object_mask=surf.object_mask, truth_normals=surf.normals)
    assert res.thresholds["t_far"] == pytest.approx(0.2 - 0.1 * 4 / 8)  # interpolated at k = 8
    assert res.info["changed"] and res.info["changed"][0] > 0
    assert len(res.info["ne"]) == res.iterations + 2
    none = ps.solve(sc.images, lay, object_mask=surf.object_mask)
    assert ps.normal_error(res.normals, surf.normals, object_mask=surf.object_mask) < \
        ps.normal_error(none.normals, surf.normals, object_mask=surf.object_mask)
    assert resolve_thresholds(16)["t_far"] == pytest.approx(0.1)  # clamped


def test_runtime_method_with_a_mask(scene, plugins):
    surf, lay, sc = scene
    ref = ps.solve(sc.images, lay, mask="Sh", object_mask=surf.object_mask)
    res = ps.solve(sc.images, lay, mask="Sh", method="mymethod", object_mask=surf.object_mask,
                   shrink=0.25)
    assert res.method == "mymethod" and res.mask == "Sh"
    assert np.array_equal(res.valid, ref.valid)  # the mask engine ran first
    assert res.info["kept"] == int(ref.valid.sum())
    np.testing.assert_allclose(res.albedo, 0.25 * ref.albedo, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(res.normals, ref.normals, atol=1e-5)
    assert res.iterations == ref.iterations  # the mask rounds, with a normal mask
    alone = ps.solve(sc.images, lay, method="mymethod")
    assert alone.iterations == 2 and alone.info["iterations"].shape == sc.images.shape[1:]
    with pytest.raises(PsbenchError, match=r"unknown option.*'shrnk'.*valid options:.*shrink"):
        ps.solve(sc.images, lay, method="mymethod", shrnk=0.5)
    with pytest.raises(PsbenchError, match=r"shrink must be a number in \(0, 1\]"):
        ps.solve(sc.images, lay, method="mymethod", shrink=1.5)
    assert "mymethod" in __import__("psbench.solve", fromlist=["METHODS"]).METHODS


def test_unknown_names_list_plugins(scene, plugins):
    surf, lay, sc = scene
    with pytest.raises(PsbenchError, match=r"valid masks: None, Th, .*RA, Dark, Far"):
        ps.solve(sc.images, lay, mask="Th-Nope")
    with pytest.raises(PsbenchError, match=r"method='nope' is not known; valid choices: .*mymethod"):
        ps.solve(sc.images, lay, method="nope")


def test_builtins_listed_without_plugins():
    assert MASKS == ("None", "Th", "NL", "xNL", "SS", "Re", "CS", "Hi", "Sh", "CJ", "RA", "SR")
    assert METHODS[:3] == ("ps", "fwlse", "wps")          # the thesis's, then the others
    assert {"robust", "trim", "l1", "sbl", "rpca", "huber", "cauchy", "tukey",
            "tsfit"} <= set(METHODS)


# ------------------------------------------------------------- a real entry point
PLUGIN = '''
import numpy as np
from psbench.registry import Mask, Method, Threshold
from psbench.solve.base import Fit, Options


def bright(images, b, ctx):
    """Local normal mask: residual above t_bright of the range."""
    r = images - ctx.S32 @ b.T
    return r <= np.float32(ctx.thresholds["t_bright"] * ctx.scale)


MASK = Mask("Bright", "normal", bright, ranges=True,
            thresholds=(Threshold("t_bright", 0.05, (0.0, 1.0)),))


def half(problem, options):
    return Fit(b=problem.start() * np.float32(0.5))


METHOD = Method("half", half, options=Options)
'''


@pytest.fixture
def entry_point_package(tmp_path):
    (tmp_path / "psb_demo_plugin.py").write_text(textwrap.dedent(PLUGIN))
    info = tmp_path / "psb_demo_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: psb-demo-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[psbench.masks]\nBright = psb_demo_plugin:MASK\n\n"
        "[psbench.methods]\nhalf = psb_demo_plugin:METHOD\n")
    sys.path.insert(0, str(tmp_path))
    registry.reload()
    yield
    sys.path.remove(str(tmp_path))
    sys.modules.pop("psb_demo_plugin", None)
    registry.reload()


def test_entry_point_plugin(scene, entry_point_package):
    surf, lay, sc = scene
    assert "Bright" in registry.names("masks") and "half" in registry.names("methods")
    assert "Th" in registry.names("masks")  # built-ins still there
    res = ps.solve(sc.images, lay, mask="Th-Bright", method="half", object_mask=surf.object_mask)
    ref = ps.solve(sc.images, lay, mask="Th-Bright", object_mask=surf.object_mask)
    assert res.mask == "Th-Bright" and res.method == "half"
    assert res.thresholds["t_bright"] == 0.05
    np.testing.assert_allclose(res.albedo, 0.5 * ref.albedo, rtol=1e-5, atol=1e-7)
    alone = ps.solve(sc.images, lay, mask="Bright", object_mask=surf.object_mask)
    assert (~alone.valid[:, surf.object_mask]).sum() > 0 and alone.iterations >= 1


def test_entry_point_plugin_gone_after_reload():
    assert "Bright" not in registry.names("masks")
    with pytest.raises(PsbenchError, match="unknown mask 'Bright'"):
        ps.solve(np.ones((8, 4, 4), np.float32), "45x8", mask="Bright")


def test_new_builtin_module_is_found_without_an_entry_point(tmp_path, monkeypatch):
    """A new module in a built-in package is registered by convention alone (one file)."""
    pkg = tmp_path / "psbtmpmasks"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "bright.py").write_text(textwrap.dedent("""
        from psbench.registry import Mask

        def bright(images, ctx):
            return images <= images.max()

        MASK = Mask("Bright", "image", bright, help="keeps everything")
    """))
    (pkg / "_private.py").write_text("raise ImportError('private modules are not scanned')")
    monkeypatch.syspath_prepend(str(tmp_path))
    name, attr, packages = registry.GROUPS["masks"]
    monkeypatch.setitem(registry.GROUPS, "masks", (name, attr, packages + ("psbtmpmasks",)))
    registry.reload("masks")
    try:
        assert "Bright" in registry.names("masks") and "Th" in registry.names("masks")
    finally:
        monkeypatch.undo()
        registry.reload("masks")
        sys.modules.pop("psbtmpmasks.bright", None)
        sys.modules.pop("psbtmpmasks", None)
    assert "Bright" not in registry.names("masks")
