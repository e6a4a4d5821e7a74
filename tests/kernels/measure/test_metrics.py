"""Error metrics against analytic values (kernels/metrics.py).

Tolerances: inputs are float32, so a perturbation d of a value y is known to about 1e-7 * y;
relative tolerances of 1e-5 cover that with room. FLIP is checked for its defining properties
(0 for identical images, growing with the error, in [0, 1]) and against flip_evaluator's own
exposure rule, not against hard-coded values.
"""

import json
import math

import numpy as np
import pytest

from classic_bake.kernels.measure import metrics as M

RNG_SEED = 20240611


def _image(h=24, w=32, c=3, seed=RNG_SEED, low=0.05, high=4.0):
    rng = np.random.default_rng(seed)
    return rng.uniform(low, high, size=(h, w, c)).astype(np.float32)


# --- identical images ------------------------------------------------------------------------


def test_identical_images_score_zero_error_and_capped_psnr():
    ref = _image()
    m = M.compare(ref, ref.copy(), settings=M.MetricSettings(flip=False, binary_threshold=0.5))
    assert (m.mse, m.rmse, m.mae, m.rel_mse, m.binary_disagreement) == (0.0, 0.0, 0.0, 0.0, 0.0)
    # Documented: identical images report PSNR_MAX_DB, never inf (JSON has no infinity).
    assert m.psnr_db == M.PSNR_MAX_DB
    assert M.psnr(ref, ref) == M.PSNR_MAX_DB
    assert m.n_valid == 24 * 32 and m.channels == 3


def test_compare_result_is_json_ready_without_nan_or_inf():
    ref = _image()
    m = M.compare(ref, ref, settings=M.MetricSettings(flip=False))
    text = json.dumps(m.to_dict(), allow_nan=False)  # raises on NaN / inf
    back = json.loads(text)
    assert back["psnr_db"] == M.PSNR_MAX_DB and back["flip"] is None
    assert set(back) >= {"mse", "rmse", "mae", "rel_mse", "psnr_db", "flip", "n_valid"}


# --- known perturbations ---------------------------------------------------------------------


@pytest.mark.parametrize("y, d", [(2.0, 0.1), (0.05, 0.2), (1.0, -0.3)])
def test_relative_perturbation_gives_known_rel_mse(y, d):
    # t = y (1 + d)  =>  (t - y)^2 / (y^2 + eps) = d^2 / (1 + eps / y^2)
    ref = np.full((8, 8, 3), y, np.float32)
    test = np.full((8, 8, 3), y * (1.0 + d), np.float32)
    expected = d * d / (1.0 + M.REL_MSE_EPS / (y * y))
    assert M.rel_mse(test, ref) == pytest.approx(expected, rel=1e-5)
    assert M.compare(test, ref, settings=M.MetricSettings(flip=False)).rel_mse == pytest.approx(
        expected, rel=1e-5
    )


def test_rel_mse_of_black_reference_is_finite_and_uses_eps():
    # Half the pixels black in both (no error), half y = 1 scaled by 1 + d: mean = half of
    # d^2 / (1 + eps). A black reference with a lit test gives t^2 / eps, finite.
    d = 0.25
    ref = np.zeros((4, 6, 1), np.float32)
    ref[:, 3:] = 1.0
    test = ref * np.float32(1.0 + d)
    assert M.rel_mse(test, ref) == pytest.approx(0.5 * d * d / (1.0 + M.REL_MSE_EPS), rel=1e-6)
    lit = np.full((4, 6, 1), 0.1, np.float32)
    value = M.rel_mse(lit, np.zeros_like(lit))
    assert math.isfinite(value) and value == pytest.approx(0.01 / M.REL_MSE_EPS, rel=1e-5)


def test_rel_mse_is_scale_invariant_with_scaled_eps():
    # (k t - k r)^2 / ((k r)^2 + k^2 eps) = (t - r)^2 / (r^2 + eps)
    ref, test = _image(seed=1), _image(seed=2)
    base = M.rel_mse(test, ref, eps=0.01)
    for k in (0.5, 3.0, 10.0):
        scaled = M.rel_mse(test * np.float32(k), ref * np.float32(k), eps=0.01 * k * k)
        assert scaled == pytest.approx(base, rel=1e-5)


def test_constant_offset_gives_known_mse_rmse_mae_and_psnr():
    c = 0.1
    ref = _image(low=0.0, high=2.0)
    ref.flat[0] = 2.0  # the reference's max, for the "reference max" peak
    test = ref + np.float32(c)
    m = M.compare(test, ref, settings=M.MetricSettings(flip=False))
    assert m.mse == pytest.approx(c * c, rel=1e-4)
    assert m.rmse == pytest.approx(c, rel=1e-4)
    assert m.mae == pytest.approx(c, rel=1e-4)
    # Default peak 1.0: PSNR = 10 log10(1 / c^2) = 20 dB.
    assert m.psnr_peak == 1.0 and m.psnr_db == pytest.approx(20.0, abs=1e-3)
    # Reference-max peak (2.0): 20 log10(2 / 0.1) = 26.0206 dB.
    peak_max = M.compare(test, ref, settings=M.MetricSettings(flip=False, psnr_peak=None))
    assert peak_max.psnr_peak == 2.0
    assert peak_max.psnr_db == pytest.approx(20 * math.log10(2.0 / c), abs=1e-3)
    assert M.psnr(test, ref, peak=None) == pytest.approx(peak_max.psnr_db)
    assert M.mse(test, ref) == pytest.approx(m.mse) and M.rmse(test, ref) == pytest.approx(m.rmse)
    assert M.mae(test, ref) == pytest.approx(m.mae)


def test_psnr_from_mse_formula_and_cap():
    assert M.psnr_from_mse(1e-4, 1.0) == pytest.approx(40.0)
    assert M.psnr_from_mse(0.25, 2.0) == pytest.approx(10 * math.log10(16.0))
    assert M.psnr_from_mse(0.0, 1.0) == M.PSNR_MAX_DB
    assert M.psnr_from_mse(1e-30, 1.0) == M.PSNR_MAX_DB


def test_binary_disagreement_counts_flipped_texels():
    ref = np.zeros((10, 10), np.float32)
    ref[:, 5:] = 1.0  # lit right half
    test = ref.copy()
    test[0, :7] = 1.0 - test[0, :7]  # 7 texels flipped
    assert M.binary_disagreement(test, ref) == pytest.approx(0.07)
    # Only values across the threshold count: 0.4 stays "off", 0.6 stays "on".
    soft = np.where(ref > 0.5, 0.6, 0.4).astype(np.float32)
    assert M.binary_disagreement(soft, ref) == 0.0
    mask = np.zeros((10, 10), bool)
    mask[0, :] = True  # row 0 only: 7 of 10 differ
    assert M.binary_disagreement(test, ref, mask) == pytest.approx(0.7)
    m = M.compare(test, ref, mask, M.MetricSettings(flip=False, binary_threshold=0.5))
    assert m.binary_disagreement == pytest.approx(0.7)


# --- masks -----------------------------------------------------------------------------------


def test_mask_excludes_background_even_when_it_holds_garbage():
    ref = _image()
    test = ref.copy()
    mask = np.ones(ref.shape[:2], bool)
    mask[:, :10] = False  # "background": huge errors and NaN there must not count
    test[:, :10] = 1e6
    ref_nan = ref.copy()
    ref_nan[:, :10] = np.nan
    for r in (ref, ref_nan):
        m = M.compare(test, r, mask, M.MetricSettings(flip=False))
        assert (m.mse, m.rel_mse, m.mae) == (0.0, 0.0, 0.0)
        assert m.n_valid == int(mask.sum())


def test_mask_averages_over_valid_pixels_only():
    ref = np.ones((4, 4, 3), np.float32)
    test = ref.copy()
    test[0, 0] = 2.0  # one pixel off by 1 in every channel
    mask = np.zeros((4, 4), bool)
    mask[0, :] = True  # 4 valid pixels, one wrong
    assert M.mse(test, ref, mask) == pytest.approx(1.0 / 4)
    assert M.mse(test, ref) == pytest.approx(1.0 / 16)


def test_error_image_matches_rel_mse_and_is_zero_off_mask():
    ref, test = _image(seed=3), _image(seed=4)
    mask = np.random.default_rng(5).random(ref.shape[:2]) > 0.3
    out = np.full(ref.shape[:2], 7.0, np.float32)  # caller-owned buffer, filled with garbage
    image = M.relative_squared_error_image(test, ref, mask, out=out)
    assert image is out and image.dtype == np.float32 and image.shape == ref.shape[:2]
    assert np.all(image[~mask] == 0.0)
    assert float(image[mask].astype(np.float64).mean()) == pytest.approx(
        M.rel_mse(test, ref, mask), rel=1e-5
    )
    images = M.error_images(test, ref, mask, M.MetricSettings(flip=False))
    np.testing.assert_allclose(images.rel_se, image, rtol=1e-6)
    assert images.flip is None


def test_two_dimensional_images_are_single_channel():
    ref = _image(c=1)
    test = ref * np.float32(1.1)
    assert M.rel_mse(test[:, :, 0], ref[:, :, 0]) == pytest.approx(M.rel_mse(test, ref))


# --- invalid inputs --------------------------------------------------------------------------


def test_invalid_inputs_raise_clear_errors():
    ref = _image()
    with pytest.raises(ValueError, match="same shape"):
        M.mse(ref[:, :-1], ref)
    with pytest.raises(ValueError, match="mask selects no pixels"):
        M.compare(ref, ref, np.zeros(ref.shape[:2], bool))
    with pytest.raises(ValueError, match="boolean"):
        M.mse(ref, ref, np.ones(ref.shape[:2], np.uint8))
    with pytest.raises(ValueError, match="mask must have shape"):
        M.mse(ref, ref, np.ones((3, 3), bool))
    for bad in (np.nan, np.inf, -np.inf):
        broken = ref.copy()
        broken[3, 4, 1] = bad
        with pytest.raises(ValueError, match="NaN or inf"):
            M.compare(broken, ref)
        with pytest.raises(ValueError, match="NaN or inf"):
            M.rel_mse(ref, broken)
    with pytest.raises(ValueError, match="non-empty"):
        M.mse(np.zeros((0, 4, 3), np.float32), np.zeros((0, 4, 3), np.float32))
    with pytest.raises(ValueError, match="real numbers"):
        M.mse(ref.astype(np.complex64), ref.astype(np.complex64))
    with pytest.raises(ValueError, match="eps"):
        M.rel_mse(ref, ref, eps=0.0)
    with pytest.raises(ValueError, match="black"):
        M.psnr(ref, np.zeros_like(ref), peak=None)
    with pytest.raises(ValueError):
        M.MetricSettings(rel_mse_eps=-1.0)
    with pytest.raises(ValueError):
        M.MetricSettings(psnr_peak=0.0)
    with pytest.raises(ValueError):
        M.MetricSettings(flip_tonemapper="filmic")
    with pytest.raises(ValueError):
        M.MetricSettings(flip_ppd=float("nan"))


def test_settings_are_frozen():
    settings = M.MetricSettings()
    with pytest.raises(AttributeError):
        settings.rel_mse_eps = 1.0  # type: ignore[misc]


# --- HDR-FLIP --------------------------------------------------------------------------------


def test_flip_is_zero_for_identical_and_grows_with_perturbation():
    pytest.importorskip("flip_evaluator")
    ref = _image(h=32, w=32)
    assert M.flip(ref, ref.copy()) == 0.0
    values = [M.flip(ref * np.float32(1.0 + d), ref) for d in (0.02, 0.1, 0.3, 1.0)]
    assert all(0.0 < v <= 1.0 for v in values)
    assert values == sorted(values) and values[-1] > 2 * values[0]
    flip_map = M.flip_error_image(ref * np.float32(1.3), ref)
    assert flip_map.shape == (32, 32) and flip_map.dtype == np.float32
    assert float(flip_map.astype(np.float64).mean()) == pytest.approx(values[2], rel=1e-5)


def test_flip_ignores_masked_pixels_and_survives_black_regions():
    pytest.importorskip("flip_evaluator")
    ref = np.zeros((32, 32, 3), np.float32)
    ref[:, 20:] = 0.8  # more than half black: the median luminance is 0
    test = ref.copy()
    test[:, :20] = 5.0  # errors only where the mask is False
    mask = np.zeros((32, 32), bool)
    mask[:, 20:] = True
    assert M.flip(test, ref, mask) == 0.0
    # Unmasked, the black median must not break the exposure range (flip_evaluator alone
    # aborts the process there); the error is large and finite.
    value = M.flip(test, ref)
    assert 0.1 < value <= 1.0
    # Both black: identical after FLIP's clamp; black reference, lit test: an error.
    black = np.zeros((16, 16, 3), np.float32)
    assert M.flip(black, black) == 0.0
    assert M.flip(black + np.float32(0.5), black) > 0.1


def test_flip_exposure_range_matches_flip_evaluator_default():
    fe = pytest.importorskip("flip_evaluator")
    ref = _image(h=32, w=32)
    _, _, used = fe.evaluate(ref, ref * np.float32(1.1), "HDR", inputsRGB=False,
                             applyMagma=False)
    start, stop = M.flip_exposure_range(ref, np.ones((32, 32), bool), "ACES")
    assert start == pytest.approx(used["startExposure"], abs=1e-4)
    assert stop == pytest.approx(used["stopExposure"], abs=1e-4)
    # And the mean FLIP equals the package's own result on a full-mask image.
    _, native, _ = fe.evaluate(ref, ref * np.float32(1.1), "HDR", inputsRGB=False,
                               applyMagma=False)
    assert M.flip(ref * np.float32(1.1), ref) == pytest.approx(native, rel=1e-4)


def test_compare_reports_flip_and_error_images_once():
    pytest.importorskip("flip_evaluator")
    ref = _image(h=32, w=32, c=4)  # alpha is ignored by FLIP
    test = ref * np.float32(1.2)
    metrics, images = M.compare_with_images(test, ref)
    assert metrics.flip == pytest.approx(
        float(images.flip.astype(np.float64).mean()), rel=1e-6
    )
    assert metrics.rel_mse == pytest.approx(float(images.rel_se.astype(np.float64).mean()),
                                            rel=1e-5)
    assert M.compare(test, ref).to_dict() == metrics.to_dict()
    with pytest.raises(ValueError, match="1, 3 or 4 channels"):
        M.flip(ref[:, :, :2], ref[:, :, :2])
