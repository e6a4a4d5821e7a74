"""Error metrics between a test image and a reference (Cycles) image: arrays in, numbers out.

Every function takes linear, scene-referred HDR images (H, W, C) float (C = 1, 3 or 4; a
(H, W) array is read as C = 1) and an optional boolean `mask` (H, W), True where a pixel or texel
is valid. Background pixels and unbaked texels are excluded by the caller through the mask; values
outside the mask are never read (they may even be NaN). Statistics are computed in float64 over the
valid pixels and all channels. Nothing here returns NaN or inf:

* an all-False mask raises ValueError (there is nothing to compare);
* a non-finite value inside the mask raises ValueError;
* identical images give PSNR = `PSNR_MAX_DB` (JSON has no infinity), every other error 0.

Formulas (t: test, r: reference, both per pixel and channel; mean over the N valid pixels x C):

| metric              | formula                                        | unit                 |
|---------------------|------------------------------------------------|----------------------|
| mse                 | mean (t - r)^2                                 | (image unit)^2       |
| rmse                | sqrt(mse)                                      | image unit           |
| mae                 | mean abs(t - r)                                | image unit           |
| rel_mse             | mean (t - r)^2 / (r^2 + eps)                   | dimensionless        |
| psnr_db             | 10 log10(peak^2 / mse), at most PSNR_MAX_DB    | dB                   |
| binary_disagreement | fraction of pixels where on(t) != on(r)        | fraction in [0, 1]   |
| flip                | mean HDR-FLIP over valid pixels                | [0, 1], 0 = same     |

Relative MSE follows the denoising literature (Rousselle, Knaus and Zwicker, "Adaptive Sampling
and Reconstruction using Greedy Error Minimization", SIGGRAPH Asia 2011, and later work such as
Bako et al., "Kernel-Predicting Convolutional Networks for Denoising Monte Carlo Renderings", 2017):
the squared error of each pixel and channel divided by the squared reference value plus a small
epsilon, so that an error is judged against the brightness it sits in. Its epsilon is the field
`MetricSettings.rel_mse_eps` (default `REL_MSE_EPS`).

PSNR convention for HDR images: the peak is 1.0 by default, the value Blender's "Standard" view
transform maps to display white, so PSNR values are comparable across scenes and techniques. Set
`MetricSettings.psnr_peak=None` to use the reference's maximum over the valid pixels instead.

HDR-FLIP (Andersson et al., "Visualizing Errors in Rendered High Dynamic Range Images",
Eurographics 2021) comes from the `flip_evaluator` package (a dev dependency, imported only when
FLIP is asked for). Its exposure range is computed here from the reference's *valid* pixels with
the paper's rule (start = log2(x_max / Y_max), stop = log2(x_max / Y_median)), because the
package computes it over the whole image (background included) and aborts the process when the
median luminance is zero. x_max solves tonemap(x_max) = 0.85 for the chosen tone mapper (the
paper's rule; flip_evaluator 1.7 uses the ACES value for every tone mapper). Negative values are
clamped to 0 (FLIP accepts non-negative input only).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

# --- named constants -------------------------------------------------------------------------

# Added to r^2 in relative MSE: keeps it finite where the reference is black (shadows, unlit
# texels); 1e-2 is the usual choice of the denoising literature (a texel of value 0.1 counts half).
REL_MSE_EPS = 1e-2
# Reported PSNR for (nearly) identical images instead of inf: JSON has no infinity, and 200 dB is
# beyond float32 resolution (one rounding step at the peak, 6e-8, is about 144 dB).
PSNR_MAX_DB = 200.0
# Default PSNR peak for HDR images: display white under Blender's Standard view transform.
PSNR_DEFAULT_PEAK = 1.0
# A binary map (shadow mask) texel is "on" above this value: halfway between shadowed 0 and lit 1.
BINARY_THRESHOLD = 0.5
# FLIP's default observer: 0.7 m from a 0.7 m wide, 3840-pixel display (pixels per degree).
FLIP_DEFAULT_PPD = 0.7 * (3840.0 / 0.7) * math.pi / 180.0
# Tone-mapped value that the brightest / median luminance is exposed to (the HDR-FLIP paper's t).
FLIP_EXPOSURE_TARGET = 0.85
# Widest exposure range, in stops: a black median would ask for infinitely many LDR evaluations;
# 12 stops spans a typical display chain and bounds the cost at 12 FLIP passes.
FLIP_MAX_STOPS = 12.0
# Rec. 709 luminance weights (linear RGB), as FLIP uses them.
REC709_LUMINANCE = (0.2126, 0.7152, 0.0722)
# The tone mappers flip_evaluator accepts.
FLIP_TONEMAPPERS = ("ACES", "HABLE", "REINHARD")


# --- settings and results --------------------------------------------------------------------


@dataclass(frozen=True)
class MetricSettings:
    """How `compare` measures.

    | field            | range          | default | meaning                                 |
    |------------------|----------------|---------|-----------------------------------------|
    | rel_mse_eps      | (0, inf)       | 0.01    | epsilon added to r^2 in relative MSE    |
    | psnr_peak        | (0, inf), None | 1.0     | PSNR peak; None: reference max (valid)  |
    | binary_threshold | float, None    | None    | set for binary maps: disagreement       |
    | flip             | bool           | True    | compute HDR-FLIP (flip_evaluator)       |
    | flip_ppd         | (0, inf)       | 67.02   | FLIP observer, pixels per degree        |
    | flip_tonemapper  | ACES/HABLE/... | "ACES"  | FLIP's assumed tone mapper              |
    """

    rel_mse_eps: float = REL_MSE_EPS
    psnr_peak: float | None = PSNR_DEFAULT_PEAK
    binary_threshold: float | None = None
    flip: bool = True
    flip_ppd: float = FLIP_DEFAULT_PPD
    flip_tonemapper: str = "ACES"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rel_mse_eps) and self.rel_mse_eps > 0.0):  # inf: every error 0
            raise ValueError(f"rel_mse_eps must be a finite value > 0, got {self.rel_mse_eps}")
        peak = self.psnr_peak
        if peak is not None and not (math.isfinite(peak) and peak > 0):
            raise ValueError(f"psnr_peak must be a finite value > 0 or None, got {self.psnr_peak}")
        if self.binary_threshold is not None and not math.isfinite(self.binary_threshold):
            raise ValueError(f"binary_threshold must be finite, got {self.binary_threshold}")
        if not (math.isfinite(self.flip_ppd) and self.flip_ppd > 0):
            raise ValueError(f"flip_ppd must be a finite value > 0, got {self.flip_ppd}")
        if self.flip_tonemapper.upper() not in FLIP_TONEMAPPERS:
            raise ValueError(
                f"flip_tonemapper must be one of {FLIP_TONEMAPPERS}, got {self.flip_tonemapper!r}"
            )


@dataclass(frozen=True)
class Metrics:
    """All errors of one test image against its reference. Plain Python numbers only.

    `flip` is None when not asked for; `binary_disagreement` is None unless the settings name a
    binary threshold. `to_dict()` gives the JSON-ready form written into metrics.json.
    """

    n_valid: int  # valid pixels (texels) compared
    channels: int
    mse: float
    rmse: float
    mae: float
    rel_mse: float
    rel_mse_eps: float
    psnr_db: float
    psnr_peak: float
    flip: float | None = None
    binary_disagreement: float | None = None

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True, eq=False)
class ErrorImages:
    """Per-pixel error images, (H, W) float32, 0 outside the mask.

    rel_se: relative squared error averaged over channels, (t - r)^2 / (r^2 + eps), >= 0.
    flip: HDR-FLIP error in [0, 1], or None when FLIP was not asked for.
    """

    rel_se: np.ndarray  # (H, W) float32, dimensionless
    flip: np.ndarray | None = None  # (H, W) float32, [0, 1]


# --- input checks ----------------------------------------------------------------------------


def _as_image(name: str, image: Any) -> np.ndarray:
    array = np.asarray(image)
    if array.dtype == np.bool_:
        array = array.astype(np.float32)
    if not (np.issubdtype(array.dtype, np.floating) or np.issubdtype(array.dtype, np.integer)):
        raise ValueError(f"{name} must hold real numbers, got dtype {array.dtype}")
    if array.ndim == 2:
        array = array[:, :, None]
    if array.ndim != 3 or array.shape[0] == 0 or array.shape[1] == 0 or array.shape[2] == 0:
        raise ValueError(f"{name} must be a non-empty (H, W, C) or (H, W) image, got {array.shape}")
    return array


def _prepare(
    test: Any, reference: Any, mask: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Check inputs; return (test, reference, valid) with valid (H, W) bool."""
    t = _as_image("test", test)
    r = _as_image("reference", reference)
    if t.shape != r.shape:
        raise ValueError(f"test {t.shape} and reference {r.shape} must have the same shape")
    if mask is None:
        valid = np.ones(t.shape[:2], dtype=bool)
    else:
        valid = np.asarray(mask)
        if valid.dtype != np.bool_:
            raise ValueError(f"mask must be a boolean array, got dtype {valid.dtype}")
        if valid.shape != t.shape[:2]:
            raise ValueError(f"mask must have shape {t.shape[:2]} (H, W), got {valid.shape}")
    if not valid.any():
        raise ValueError(
            "mask selects no pixels: nothing to compare (every pixel is background or unbaked)"
        )
    for name, array in (("test", t), ("reference", r)):
        if not np.isfinite(array[valid]).all():
            raise ValueError(f"{name} holds NaN or inf inside the valid region")
    return t, r, valid


def _valid_values(
    test: Any, reference: Any, mask: Any
) -> tuple[np.ndarray, np.ndarray]:
    """(N, C) float64 test and reference values of the valid pixels."""
    t, r, valid = _prepare(test, reference, mask)
    return t[valid].astype(np.float64), r[valid].astype(np.float64)


# --- scalar metrics --------------------------------------------------------------------------


def mse(test: Any, reference: Any, mask: Any = None) -> float:
    """Mean squared error over valid pixels and channels, (image unit)^2."""
    t, r = _valid_values(test, reference, mask)
    return float(np.mean((t - r) ** 2))


def rmse(test: Any, reference: Any, mask: Any = None) -> float:
    """Root mean squared error, image unit."""
    return math.sqrt(mse(test, reference, mask))


def mae(test: Any, reference: Any, mask: Any = None) -> float:
    """Mean absolute error over valid pixels and channels, image unit."""
    t, r = _valid_values(test, reference, mask)
    return float(np.mean(np.abs(t - r)))


def rel_mse(test: Any, reference: Any, mask: Any = None, eps: float = REL_MSE_EPS) -> float:
    """Relative MSE: mean over valid pixels and channels of (t - r)^2 / (r^2 + eps)."""
    if not (math.isfinite(eps) and eps > 0.0):
        raise ValueError(f"eps must be a finite value > 0, got {eps}")
    t, r = _valid_values(test, reference, mask)
    return float(np.mean((t - r) ** 2 / (r * r + eps)))


def psnr_from_mse(mse_value: float, peak: float) -> float:
    """10 log10(peak^2 / mse) in dB, capped at PSNR_MAX_DB (identical images)."""
    if not (math.isfinite(peak) and peak > 0.0):
        raise ValueError(f"PSNR peak must be a finite value > 0, got {peak}")
    if not (math.isfinite(mse_value) and mse_value >= 0.0):
        raise ValueError(f"MSE must be finite and >= 0, got {mse_value}")
    if mse_value <= peak * peak * 10.0 ** (-PSNR_MAX_DB / 10.0):
        return PSNR_MAX_DB
    return 10.0 * math.log10(peak * peak / mse_value)


def _psnr_peak(r_valid: np.ndarray, peak: float | None) -> float:
    if peak is not None:
        return float(peak)
    reference_max = float(r_valid.max())
    if reference_max <= 0.0:
        raise ValueError(
            "PSNR peak 'reference max' is undefined: the reference is black in the valid "
            "region; pass a fixed psnr_peak such as 1.0"
        )
    return reference_max


def psnr(
    test: Any, reference: Any, mask: Any = None, peak: float | None = PSNR_DEFAULT_PEAK
) -> float:
    """PSNR in dB; `peak` 1.0 by default, None for the reference's max over valid pixels."""
    t, r = _valid_values(test, reference, mask)
    return psnr_from_mse(float(np.mean((t - r) ** 2)), _psnr_peak(r, peak))


def binary_disagreement(
    test: Any, reference: Any, mask: Any = None, threshold: float = BINARY_THRESHOLD
) -> float:
    """Fraction of valid texels whose on/off state differs; a texel is on when the mean of its
    channels is above `threshold` (for shadow masks: lit)."""
    t, r = _valid_values(test, reference, mask)
    t_on = t.mean(axis=1) > threshold  # (N,) bool
    r_on = r.mean(axis=1) > threshold
    return float(np.mean(t_on != r_on))


# --- HDR-FLIP --------------------------------------------------------------------------------


def _rgb3(image: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32 C-contiguous, non-negative: what flip_evaluator accepts."""
    channels = image.shape[2]
    if channels == 1:
        rgb = np.repeat(image, 3, axis=2)
    elif channels >= 3:
        rgb = image[:, :, :3]  # alpha is not colour
    else:
        raise ValueError(f"FLIP needs 1, 3 or 4 channels, got {channels}")
    return np.ascontiguousarray(np.maximum(rgb, 0.0), dtype=np.float32)


def _luminance(rgb: np.ndarray) -> np.ndarray:
    """(..., 3) linear Rec. 709 -> (...) luminance."""
    return rgb @ np.asarray(REC709_LUMINANCE, dtype=rgb.dtype)


def _tonemap_coefficients(tonemapper: str) -> tuple[float, ...]:
    """(k0..k5) of FLIP's rational tone curve (k0 x^2 + k1 x + k2) / (k3 x^2 + k4 x + k5)."""
    name = tonemapper.upper()
    if name == "REINHARD":
        return (0.0, 1.0, 0.0, 0.0, 1.0, 1.0)
    if name == "HABLE":
        a, b, c, d, e, f, white = 0.15, 0.50, 0.10, 0.20, 0.02, 0.30, 11.2
        k = [a * f - a * e, c * b * f - b * e, 0.0, a * f, b * f, d * f * f]
        white_scale = (k[3] * white**2 + k[4] * white + k[5]) / (k[0] * white**2 + k[1] * white)
        return (4 * k[0] * white_scale, 2 * k[1] * white_scale, 0.0, 4 * k[3], 2 * k[4], k[5])
    # ACES fit (Narkowicz 2016) with FLIP's 0.6 pre-exposure folded in.
    return (0.6 * 0.6 * 2.51, 0.6 * 0.03, 0.0, 0.6 * 0.6 * 2.43, 0.6 * 0.59, 0.14)


def _exposed_value(tonemapper: str, target: float = FLIP_EXPOSURE_TARGET) -> float:
    """x such that tonemap(x) = target: the value the brightest pixel is exposed to."""
    k0, k1, k2, k3, k4, k5 = _tonemap_coefficients(tonemapper)
    if k0 == 0.0 and k3 == 0.0:  # Reinhard: linear over linear
        return target * k5 / (k1 - target * k4)
    c0 = (k1 - k4 * target) / (k0 - k3 * target)
    c1 = (k2 - k5 * target) / (k0 - k3 * target)
    return -0.5 * c0 + math.sqrt((0.5 * c0) ** 2 - c1)


def flip_exposure_range(
    reference_rgb: np.ndarray, valid: np.ndarray, tonemapper: str = "ACES"
) -> tuple[float, float] | None:
    """HDR-FLIP's (start, stop) exposures, in stops, from the valid pixels of the reference.

    start = log2(x_max / Y_max), stop = log2(x_max / Y_median), with the median floored at
    Y_max * 2^-FLIP_MAX_STOPS. None when the valid region is black (Y_max = 0).
    """
    lum = _luminance(reference_rgb[valid].astype(np.float64))  # (N,)
    y_max = float(lum.max())
    if y_max <= 0.0:
        return None
    y_median = max(float(np.median(lum)), y_max * 2.0 ** (-FLIP_MAX_STOPS))
    x_max = _exposed_value(tonemapper)
    return math.log2(x_max / y_max), math.log2(x_max / y_median)


def _flip_map(
    t: np.ndarray, r: np.ndarray, valid: np.ndarray, settings: MetricSettings
) -> np.ndarray:
    """(H, W) float32 HDR-FLIP map, 0 outside `valid`. Inputs already checked by _prepare."""
    try:
        import flip_evaluator
    except ImportError as error:  # a dev dependency: say how to go on without it
        raise ImportError(
            "HDR-FLIP needs the 'flip-evaluator' package (requirements/dev.txt); "
            "install it or use MetricSettings(flip=False)"
        ) from error
    r_clean = np.where(valid[:, :, None], r, 0.0)  # off-mask values may be NaN: never read
    # Outside the mask the test takes the reference's values: no error starts there, and edges
    # of the valid region look the same in both images.
    t_clean = np.where(valid[:, :, None], t, r_clean)
    r_rgb = _rgb3(r_clean)  # (H, W, 3) float32, >= 0
    t_rgb = _rgb3(t_clean)
    exposures = flip_exposure_range(r_rgb, valid, settings.flip_tonemapper)
    if exposures is None:  # black reference: expose for the test instead, if it has light
        exposures = flip_exposure_range(t_rgb, valid, settings.flip_tonemapper)
    if exposures is None:  # both black where valid: identical after FLIP's clamp to 0
        return np.zeros(valid.shape, dtype=np.float32)
    start, stop = exposures
    parameters = {
        "ppd": float(settings.flip_ppd),
        "startExposure": float(start),
        "stopExposure": float(stop),
        "tonemapper": settings.flip_tonemapper.upper(),
    }
    error_map, _mean, _used = flip_evaluator.evaluate(
        r_rgb, t_rgb, "HDR", inputsRGB=False, applyMagma=False, computeMeanError=False,
        parameters=parameters,
    )
    flip_map = np.asarray(error_map, dtype=np.float32).reshape(valid.shape)  # (H, W), [0, 1]
    return np.where(valid, flip_map, np.float32(0.0))


def flip(
    test: Any, reference: Any, mask: Any = None, settings: MetricSettings | None = None
) -> float:
    """Mean HDR-FLIP error over valid pixels, in [0, 1]."""
    settings = settings or MetricSettings()
    t, r, valid = _prepare(test, reference, mask)
    return float(_flip_map(t, r, valid, settings)[valid].astype(np.float64).mean())


# --- error images ----------------------------------------------------------------------------


def relative_squared_error_image(
    test: Any,
    reference: Any,
    mask: Any = None,
    eps: float = REL_MSE_EPS,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """(H, W) float32 per-pixel (t - r)^2 / (r^2 + eps), averaged over channels; 0 off-mask.

    Its mean over the valid pixels equals `rel_mse`. `out`: optional caller-owned (H, W) float32.
    """
    if not (math.isfinite(eps) and eps > 0.0):
        raise ValueError(f"eps must be a finite value > 0, got {eps}")
    t, r, valid = _prepare(test, reference, mask)
    if out is None:
        out = np.zeros(valid.shape, dtype=np.float32)
    elif out.shape != valid.shape or out.dtype != np.float32:
        raise ValueError(f"out must be {valid.shape} float32, got {out.shape} {out.dtype}")
    else:
        out.fill(0.0)
    tv = t[valid].astype(np.float64)  # (N, C)
    rv = r[valid].astype(np.float64)
    out[valid] = np.mean((tv - rv) ** 2 / (rv * rv + eps), axis=1)
    return out


def flip_error_image(
    test: Any, reference: Any, mask: Any = None, settings: MetricSettings | None = None
) -> np.ndarray:
    """(H, W) float32 HDR-FLIP error map in [0, 1]; 0 outside the mask."""
    settings = settings or MetricSettings()
    t, r, valid = _prepare(test, reference, mask)
    return _flip_map(t, r, valid, settings)


# --- everything at once ----------------------------------------------------------------------


def compare_with_images(
    test: Any, reference: Any, mask: Any = None, settings: MetricSettings | None = None
) -> tuple[Metrics, ErrorImages]:
    """All metrics and the per-pixel error images, computing FLIP once."""
    settings = settings or MetricSettings()
    t, r, valid = _prepare(test, reference, mask)
    tv = t[valid].astype(np.float64)  # (N, C)
    rv = r[valid].astype(np.float64)
    diff2 = (tv - rv) ** 2
    rel_se = diff2 / (rv * rv + settings.rel_mse_eps)  # (N, C)
    mse_value = float(diff2.mean())
    peak = _psnr_peak(rv, settings.psnr_peak)

    rel_se_image = np.zeros(valid.shape, dtype=np.float32)
    rel_se_image[valid] = rel_se.mean(axis=1)

    flip_map = None
    flip_mean = None
    if settings.flip:
        flip_map = _flip_map(t, r, valid, settings)
        flip_mean = float(flip_map[valid].astype(np.float64).mean())

    disagreement = None
    if settings.binary_threshold is not None:
        t_on = tv.mean(axis=1) > settings.binary_threshold
        r_on = rv.mean(axis=1) > settings.binary_threshold
        disagreement = float(np.mean(t_on != r_on))

    metrics = Metrics(
        n_valid=int(valid.sum()),
        channels=int(t.shape[2]),
        mse=mse_value,
        rmse=math.sqrt(mse_value),
        mae=float(np.abs(tv - rv).mean()),
        rel_mse=float(rel_se.mean()),
        rel_mse_eps=float(settings.rel_mse_eps),
        psnr_db=psnr_from_mse(mse_value, peak),
        psnr_peak=peak,
        flip=flip_mean,
        binary_disagreement=disagreement,
    )
    return metrics, ErrorImages(rel_se=rel_se_image, flip=flip_map)


def compare(
    test: Any, reference: Any, mask: Any = None, settings: MetricSettings | None = None
) -> Metrics:
    """Every metric of `test` against `reference` over the valid pixels (see module table)."""
    return compare_with_images(test, reference, mask, settings)[0]


def error_images(
    test: Any, reference: Any, mask: Any = None, settings: MetricSettings | None = None
) -> ErrorImages:
    """Per-pixel relative squared error and (if settings.flip) HDR-FLIP maps, (H, W) float32."""
    return compare_with_images(test, reference, mask, settings)[1]
