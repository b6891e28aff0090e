"""Bad input, as a new user gives it: psbench's own one-line error naming the argument,
or a documented finite result -- never a bare numpy / Python error, never a traceback
at the command line (issue 11: A1-A7, C1-C3, R1 and the API in general).

API cases call the public functions; CLI cases call the entry points in-process
(``main(args)``), which is what the console scripts run.
"""
import warnings

import numpy as np
import pytest

import psbench as ps
from psbench import PsbenchError

# ---------------------------------------------------------------------------- fixtures
SURF = ps.make_surface("sombrero2", size=32)
LAY = ps.layout("45x8")
LAY2 = ps.layout("30x8+60x8")
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    IM = ps.render(SURF, LAY, noise=0.0).images
    IM2 = ps.render(SURF, LAY2, noise=0.0).images
OM = SURF.object_mask
NE_BASE = ps.normal_error(ps.solve(IM, LAY, mask="Th", object_mask=OM).normals, SURF.normals,
                          object_mask=OM)

# (id, callable, words the error must contain); each must raise PsbenchError (one line)
API = [
    ("images-2d", lambda: ps.solve(IM[0], LAY), ["images", "(k, H, W)"]),
    ("images-4d", lambda: ps.solve(IM[None], LAY), ["images", "(k, H, W)"]),
    ("images-empty-pixels", lambda: ps.solve(np.zeros((8, 0, 0), np.float32), LAY),
     ["images", "pixel"]),
    ("images-ragged", lambda: ps.solve([np.zeros((4, 4)), np.zeros((5, 5))] * 4, LAY),
     ["images", "equal-size"]),
    ("images-strings", lambda: ps.solve(np.full((8, 4, 4), "a"), LAY), ["images", "numeric"]),
    ("images-bool", lambda: ps.solve(IM > 0, LAY), ["images", "numeric"]),
    ("images-complex", lambda: ps.solve(IM.astype(complex), LAY), ["images", "real"]),
    ("images-signed-int", lambda: ps.solve(IM.astype(np.int16), LAY), ["images", "signed"]),
    ("images-nan", lambda: ps.solve(np.where(IM > 0.5, np.nan, IM), LAY), ["images", "NaN"]),
    ("images-inf", lambda: ps.solve(np.where(IM > 0.5, np.inf, IM), LAY), ["images", "NaN/inf"]),
    ("images-negated", lambda: ps.solve(-IM, LAY), ["images", "negative", ">= 0"]),
    ("images-too-few", lambda: ps.solve(IM[:2], LAY.subset([0, 1])), ["3"]),
    ("images-none", lambda: ps.solve(None, LAY), ["images"]),
    ("lights-count", lambda: ps.solve(IM, LAY2), ["lights", "16", "8"]),
    ("lights-bad-notation", lambda: ps.solve(IM, "45y8"), ["lights", "45y8"]),
    ("lights-zenith-90", lambda: ps.layout("90x8"), ["zenith", "90"]),
    ("lights-count-0", lambda: ps.layout("45x0"), ["45x0"]),
    ("lights-nan", lambda: ps.layout(np.full((8, 3), np.nan)), ["lights", "NaN"]),
    ("lights-shape", lambda: ps.layout(np.ones((8, 2))), ["lights", "(k, 3)"]),
    ("lights-below", lambda: ps.layout(np.tile([0.0, 0.5, -1.0], (8, 1))), ["lights", "z < 0"]),
    ("lights-zero-vector", lambda: ps.layout(np.zeros((8, 3))), ["lights", "zero"]),
    ("lights-coplanar", lambda: ps.layout("0x8"), ["degenerate"]),
    ("power-negative", lambda: ps.layout("45x8", power=-1), ["power", "> 0"]),
    ("power-tiny", lambda: ps.layout("45x8", power=1e-300), ["power", "1e-30"]),
    ("power-huge", lambda: ps.layout("45x8", power=1e40), ["power", "1e+30"]),
    ("power-shape", lambda: ps.layout("45x8", power=[1, 2]), ["power", "(8,)"]),
    ("mask-unknown", lambda: ps.solve(IM, LAY, mask="Bogus"), ["Bogus", "Th", "RA"]),
    ("mask-type", lambda: ps.solve(IM, LAY, mask=3), ["mask"]),
    ("mask-NL-count", lambda: ps.solve(IM, LAY, mask="NL"), ["NL", "4 images"]),
    ("mask-CJ-combined", lambda: ps.solve(IM, LAY, mask="CJ-Th"), ["CJ"]),
    ("method-unknown", lambda: ps.solve(IM, LAY, method="magic"), ["magic", "wps"]),
    ("wps-one-ring", lambda: ps.solve(IM, LAY, method="wps"), ["single ring", "WPS"]),
    ("wps-weight-unknown", lambda: ps.solve(IM2, LAY2, method="wps", weight="bogus"),
     ["weight", "bogus"]),
    ("option-unknown", lambda: ps.solve(IM, LAY, bogus=1), ["bogus", "max_iter"]),
    ("max-iter-negative", lambda: ps.solve(IM, LAY, max_iter=-1), ["max_iter"]),
    ("th-scope-unknown", lambda: ps.solve(IM, LAY, th_scope="nowhere"), ["th_scope", "pixel"]),
    ("threshold-range", lambda: ps.solve(IM, LAY, mask="Th", thresholds={"k_low": 2}),
     ["k_low", "range"]),
    ("threshold-unknown", lambda: ps.solve(IM, LAY, mask="Th", thresholds={"k_lo": 0.1}),
     ["k_lo"]),
    ("object-mask-shape", lambda: ps.solve(IM, LAY, object_mask=OM[:-1]), ["object_mask", "shape"]),
    ("object-mask-floats", lambda: ps.solve(IM, LAY, object_mask=np.where(OM, 0.3, 0.0)),
     ["object_mask", "0 and 1", "0.3"]),
    ("object-mask-nan", lambda: ps.solve(IM, LAY, object_mask=np.where(
        np.arange(OM.size).reshape(OM.shape) == 5, np.nan, 1.0)), ["object_mask", "nan"]),
    ("object-mask-255", lambda: ps.solve(IM, LAY, object_mask=OM.astype(np.uint8) * 255),
     ["object_mask", "255"]),
    ("object-mask-strings", lambda: ps.solve(IM, LAY, object_mask=np.where(OM, "a", "")),
     ["object_mask", "bool"]),
    ("object-mask-empty", lambda: ps.solve(IM, LAY, object_mask=np.zeros_like(OM)),
     ["object_mask", "no pixel"]),
    ("truth-normals-shape", lambda: ps.solve(IM, LAY, truth_normals=np.ones((3, 3, 3))),
     ["truth_normals"]),
    ("surface-unknown", lambda: ps.make_surface("blob"), ["blob", "semisphere"]),
    ("surface-size", lambda: ps.make_surface("semisphere", size=-5), ["size", "16"]),
    ("surface-size-str", lambda: ps.make_surface("semisphere", size="big"), ["size"]),
    ("render-model", lambda: ps.render(SURF, LAY, model="disney"), ["model", "ts"]),
    ("render-noise", lambda: ps.render(SURF, LAY, noise=-1), ["noise", ">= 0"]),
    ("render-quantize", lambda: ps.render(SURF, LAY, quantize=99), ["quantize", "1..16"]),
    ("render-shadows", lambda: ps.render(SURF, LAY, shadows="some"), ["shadows"]),
    ("render-seed", lambda: ps.render(SURF, LAY, seed="x"), ["seed"]),
    ("integrate-method", lambda: ps.integrate(SURF.normals, integrator="magic"), ["integrator", "poisson"]),
    ("integrate-maxiter-str", lambda: ps.integrate(SURF.normals, maxiter="a"), ["maxiter"]),
    ("integrate-maxiter-0", lambda: ps.integrate(SURF.normals, maxiter=0), ["maxiter", ">= 1"]),
    ("integrate-maxiter-frac", lambda: ps.integrate(SURF.normals, maxiter=2.5), ["maxiter"]),
    ("integrate-tol-str", lambda: ps.integrate(SURF.normals, tol="x"), ["tol"]),
    ("integrate-tol-nan", lambda: ps.integrate(SURF.normals, tol=float("nan")), ["tol"]),
    ("integrate-nz-min", lambda: ps.integrate(SURF.normals, nz_min=2), ["nz_min"]),
    ("integrate-normals-nan", lambda: ps.integrate(np.full((8, 8, 3), np.nan)), ["normals", "NaN"]),
    ("integrate-normals-shape", lambda: ps.integrate(np.ones((8, 8))), ["normals", "(H, W, 3)"]),
    ("integrate-normals-ragged", lambda: ps.integrate([[[0, 0, 1]], [[0, 0, 1], [0, 0, 1]]]),
     ["normals"]),
    ("integrate-mask-floats", lambda: ps.integrate(SURF.normals, object_mask=OM * 0.5),
     ["object_mask"]),
    ("cond-nan", lambda: ps.cond(np.full((8, 3), np.nan)), ["S", "NaN"]),
    ("cond-shape", lambda: ps.cond(np.ones((8, 2))), ["S", "(k, 3)"]),
    ("cond-strings", lambda: ps.cond([["a", "b", "c"]] * 3), ["S"]),
    ("normal-error-shape", lambda: ps.normal_error(np.ones((4, 4, 3)), SURF.normals),
     ["truth", "shape"]),
    ("normal-error-mask", lambda: ps.normal_error(SURF.normals, SURF.normals,
                                                  object_mask=np.full(OM.shape, 0.5)),
     ["object_mask"]),
]


@pytest.mark.parametrize("name,call,words", API, ids=[a[0] for a in API])
def test_api_refuses_with_one_named_line(name, call, words):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(PsbenchError) as err:
            call()
    msg = str(err.value)
    assert "\n" not in msg, msg
    for w in words:
        assert w in msg, (w, msg)


# documented finite results (scale invariance, counters, degenerate but valid input)
def _ne(res):
    return ps.normal_error(res.normals, SURF.normals, object_mask=OM)


@pytest.mark.parametrize("scale", [1e-30, 1e-6, 2.0 ** -20, 1e19, 1e30])
def test_images_in_any_unit_give_the_same_normals(scale):
    """A2 / A3: images x 1e-6 (or x 1e19) give the same normals, finite albedo."""
    res = ps.solve(IM * np.float32(scale), LAY, mask="Th", object_mask=OM)
    assert np.isfinite(res.albedo).all() and np.isfinite(res.normals).all()
    assert np.isfinite(res.residual).all()
    assert _ne(res) == pytest.approx(NE_BASE, abs=1e-3)
    if scale == 2.0 ** -20:                    # a power of two: exactly the same
        assert _ne(res) == NE_BASE


@pytest.mark.parametrize("power", [1e-30, 1e30])
def test_light_power_does_not_change_the_normals(power):
    lay = ps.layout("45x8", power=power)
    with warnings.catch_warnings():
        warnings.simplefilter("error")         # no overflow warnings either
        img = ps.render(SURF, lay, noise=0.0).images
        res = ps.solve(img, lay, mask="Th", object_mask=OM, weighted=True)
    ref = ps.solve(IM, LAY, mask="Th", object_mask=OM, weighted=True)
    assert _ne(res) == pytest.approx(_ne(ref), abs=1e-3)
    assert np.isfinite(res.albedo).all()


def test_non_representable_albedo_is_an_error_not_nan():
    """A3: albedo = I / mu beyond float32 is refused with one line."""
    with pytest.raises(PsbenchError, match="not finite"):
        ps.solve(IM * np.float32(1e30), ps.layout("45x8", power=1e-29), mask="Th")


def test_completion_counter_and_indices_beyond_255_lights():
    """A1: 300 lights, a pixel with exactly 256 valid observations keeps them (a uint8
    count wrapped to 0 and added three masked ones)."""
    lay = ps.layout("20x75+35x75+50x75+65x75")
    rng = np.random.default_rng(0)
    im = rng.uniform(0.12, 0.3, (lay.k, 6, 6)).astype(np.float32)
    im[:, 1, 1], im[:, 1, 2] = 1.0, 0.0           # each image's range is [0, 1]
    dark = rng.choice(lay.k, lay.k - 256, replace=False)
    im[dark, 0, 0] = 0.0                          # below Th's lower bound
    res = ps.solve(im, lay, mask="Th")
    assert res.valid[:, 0, 0].sum() == 256 and not res.valid[dark, 0, 0].any()


def test_completer_matches_reference_rule_for_many_lights():
    from psbench.solve import kernel
    from psbench.solve._engine import _Completer

    rng = np.random.default_rng(1)
    k, n = 300, 400
    im = rng.uniform(0.1, 1.0, (k, 1, n)).astype(np.float32)
    lay = ps.layout("20x75+35x75+50x75+65x75")
    valid = rng.random((k, 1, n)) < 0.004            # mostly < 3 valid per pixel
    b = kernel.ls(im, lay.S)
    ref = kernel.complete_three(valid, kernel.residuals(im, b, lay.S))
    got = _Completer(im, lay.S)(valid.reshape(k, -1).copy()).reshape(k, 1, n)
    assert (got == ref).all() and got.sum(axis=0).min() >= 3


def test_small_negative_values_are_accepted():
    """Noise makes some intensities negative: accepted (documented)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        img = ps.render(SURF, LAY, noise=0.2, seed=1).images
    assert (img < 0).any()
    assert np.isfinite(ps.solve(img, LAY, mask="Th").normals).all()


def test_zero_one_masks_of_any_number_type_are_accepted():
    for m in (OM.astype(np.uint8), OM.astype(float), OM.astype(np.int64)):
        res = ps.solve(IM, LAY, object_mask=m)
        assert np.isfinite(res.normals).all()


# ---------------------------------------------------------------------------- CLI
def _run_main(capsys, main, args):
    try:
        code = main(list(args))
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr()
    return (0 if code is None else code), out.out, out.err


PSBENCH = [
    ("nosie", ["+nosie=0.3"], ["nosie", "noise"]),
    ("unknown-key", ["colour=red"], ["colour"]),
    ("size-neg", ["size=-5"], ["size", "16"]),
    ("size-str", ["size=big"], ["size", "integer"]),
    ("noise-neg", ["noise=-1", "size=16"], ["noise", ">= 0"]),
    ("quantize", ["quantize=99", "size=16"], ["quantize", "1..16"]),
    ("threshold", ["+thresholds.k_low=2", "size=16"], ["k_low", "range"]),
    ("wps-one-ring", ["method=wps", "size=16"], ["single ring"]),
    ("nl-count", ["mask=NL", "size=16"], ["NL", "4 images"]),
    ("mask-unknown", ["mask=Bogus", "size=16"], ["Bogus", "Th"]),
    ("method-unknown", ["method=magic", "size=16"], ["magic"]),
    ("surface-unknown", ["surface=blob"], ["blob", "semisphere"]),
    ("surface-file-missing", ["surface=/nonexistent/h.npy"], ["does not exist"]),
    ("lights", ["lights=45y8", "size=16"], ["45y8"]),
    ("option-unknown", ["options.bogus=1", "size=16"], ["bogus", "max_iter"]),
    ("option-value", ["options.max_iter=-3", "size=16"], ["max_iter"]),
    ("th-scope", ["th_scope=nowhere", "size=16"], ["th_scope"]),
    ("model", ["model=disney", "size=16"], ["model"]),
    ("data-missing", ["data=/nonexistent/folder"], ["data", "not a folder"]),
    ("results-dir", ["results_dir=/proc/x", "size=16"], ["results_dir", "not writable"]),
    ("results-file", ["results_dir=/etc/hostname", "size=16"], ["results_dir", "not writable"]),
    ("memory", ["size=60000"], ["GB (estimated)", "size="]),
    ("experiment-unknown", ["+experiment=table9_9"], ["table9_9", "table5_3"]),
    ("experiment-scale", ["+experiment=table5_3", "scale=huge"], ["scale", "ci"]),
    ("sweep-bad-job", ["-m", "size=16", "mask=Th,NL"], ["NL", "4 images"]),
    ("sweep-bad-key", ["-m", "size=16", "+nosie=0.1,0.2"], ["nosie"]),
    ("rerun-value", ["rerun=maybe", "size=16"], ["rerun"]),
]


@pytest.mark.parametrize("name,args,words", PSBENCH, ids=[a[0] for a in PSBENCH])
def test_psbench_cli_refuses_with_one_line_exit_2(tmp_path, monkeypatch, capsys, name, args,
                                                  words):
    from psbench.harness.app import main

    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("PSBENCH_RESULTS", raising=False)
    code, out, err = _run_main(capsys, main, args)
    assert code == 2, (out, err)
    assert "Traceback" not in out + err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("psbench: error:"), err
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert not list(tmp_path.rglob("*.parquet"))          # nothing stored


CAPTURE = [
    ("current-abc", ["current=abc"], ["current", "integer"]),
    ("size-abc", ["size=abc"], ["size", "integer"]),
    ("timeout-neg", ["timeout=-1"], ["timeout", "> 0"]),
    ("timeout-nan", ["timeout=nan"], ["timeout", "finite"]),
    ("progress", ["progress=maybe"], ["progress", "true or false"]),
    ("gamma-zero", ["gamma=0"], ["gamma"]),
    ("unknown-key", ["colour=red"], ["colour"]),
    ("rig-unknown", ["rig=laser"], ["rig", "sim"]),
    ("out-empty", ["out="], ["out", "folder path"]),
    ("not-key-value", ["--fast"], ["--fast", "key=value"]),
]


@pytest.mark.parametrize("name,args,words", CAPTURE, ids=[a[0] for a in CAPTURE])
def test_capture_cli_refuses_with_one_line_exit_2(tmp_path, capsys, name, args, words):
    from psbench.capture.cli import main

    out_arg = [] if name == "out-empty" else [f"out={tmp_path / 'cap'}"]
    code, out, err = _run_main(capsys, main, ["rig=sim", *out_arg, *args])
    assert code == 2, (out, err)
    assert "Traceback" not in out + err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("psbench-capture: error:"), err
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert not (tmp_path / "cap").exists()


RESULTS = [
    ("summary-column", ["summary", "--by", "colour"], ["colour"]),
    ("sweep-name", ["ls", "--sweep", "../x"], ["sweep"]),
]


@pytest.mark.parametrize("name,args,words", RESULTS, ids=[a[0] for a in RESULTS])
def test_results_cli_one_line(tmp_path, capsys, name, args, words):
    from psbench.harness import store
    from psbench.harness.cli import main

    store.write_row(tmp_path, dict(run_id="a", sweep="s", status="ok", kind="noop"))
    code, out, err = _run_main(capsys, main, [*args, "--root", str(tmp_path)])
    assert code == 2 and "Traceback" not in out + err
    assert all(w in err for w in words), err
