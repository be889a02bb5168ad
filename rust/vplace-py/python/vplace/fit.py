"""Features and regression at the numpy level (DESIGN: Features and label, Regression).

``fit(capture)`` extracts the per-cell features of a captured view (``vplace._native``), fits the
luminance difference between its GI and direct images on them, and returns a :class:`FitResult`:
coefficients, weights, the kept and dropped features with the reason, R^2, a readable table
(``str()``), JSON save and load, and ``predict`` for another view of the same scene (no GI render
needed there).

``fit_design(x, y)`` runs the same solver on a given design matrix.

Decisions (see also ``vplace_core::features`` and ``vplace_core::regression``):

- Covered pixels holding NaN or inf in any pass are masked (treated as uncovered) and counted in
  ``FitResult.masked_pixels``; a design matrix given to ``fit_design`` with NaN or inf is an
  ``InputError``.
- The strongest light, when the capture lists several lights, is the one with the largest
  luminance of irradiance at the mean covered position: ``P / (4 pi r^2)`` for a point or spot,
  ``P / (pi r^2)`` for an area light, ``P`` (W/m^2) for a sun.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from vplace import _native

FEATURES: tuple[tuple[str, str, str], ...] = tuple(_native.feature_registry())
"""The feature registry: ``(name, doc, origin)`` per column, origin ``"paper"`` or ``"ours"``."""

FEATURE_NAMES: tuple[str, ...] = tuple(name for name, _, _ in FEATURES)

_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
_FORMAT = "vplace.fit"
_VERSION = 1


def _get(capture: Any, name: str, required: bool = True) -> Any:
    if isinstance(capture, Mapping):
        value = capture.get(name)
    else:
        value = getattr(capture, name, None)
    if value is None and required:
        raise _native.InputError(f"capture has no {name!r} array")
    return value


def _luminance(power: Any) -> float:
    p = np.asarray(power, dtype=np.float64).reshape(-1)
    return float(p[0]) if p.size == 1 else float(p[:3] @ _LUMINANCE)


def _strongest(lights: Sequence[Any], centre: np.ndarray) -> tuple[str, list[float]] | None:
    best: tuple[float, tuple[str, list[float]]] | None = None
    for light in lights:
        kind = str(_get(light, "type")).lower()
        power = _luminance(_get(light, "power"))
        if kind == "sun":
            irradiance = power
            found = ("direction", [float(v) for v in _get(light, "direction")])
        else:
            pos = np.asarray(_get(light, "position"), dtype=np.float64)
            r2 = max(float(np.sum((pos - centre) ** 2)), 1e-12)
            irradiance = power / ((math.pi if kind == "area" else 4 * math.pi) * r2)
            found = ("position", [float(v) for v in pos])
        if best is None or irradiance > best[0]:
            best = (irradiance, found)
    return None if best is None else best[1]


def _light(capture: Any, light: Any) -> tuple[str, list[float]] | None:
    """``("position" | "direction", xyz)`` of the strongest light, or None."""
    if light is None:
        for key in ("light_position", "light_direction"):
            value = _get(capture, key, required=False)
            if value is not None:
                return (key.removeprefix("light_"), [float(v) for v in value])
        lights = _get(capture, "lights", required=False)
        if not lights:
            return None
        pos = np.asarray(_get(capture, "position"), dtype=np.float64)
        covered = np.asarray(_get(capture, "covered"), dtype=bool)
        centre = pos[covered].mean(axis=0) if covered.any() else np.zeros(3)
        return _strongest(lights, centre)
    if isinstance(light, Mapping):
        for key in ("position", "direction"):
            if light.get(key) is not None:
                return (key, [float(v) for v in light[key]])
        raise _native.InputError("light must give 'position' or 'direction'")
    kind, xyz = light
    if kind not in ("position", "direction"):
        raise _native.InputError(f"light kind must be 'position' or 'direction', got {kind!r}")
    return (kind, [float(v) for v in xyz])


def _light_kwargs(light: tuple[str, list[float]] | None) -> dict[str, Any]:
    if light is None:
        return {}
    return {f"light_{light[0]}": light[1]}


def _passes(capture: Any) -> dict[str, Any]:
    out = {
        name: _get(capture, name)
        for name in ("position", "normal", "albedo", "depth", "direct", "covered")
    }
    specular = _get(capture, "specular", required=False)
    if specular is not None:
        out["specular"] = specular
    return out


def _reason_text(d: Mapping[str, Any], names: Sequence[str]) -> str:
    reason = d["reason"]
    if reason == "constant":
        return "constant over the cells"
    if reason == "constant_label":
        return "the label is constant"
    if reason == "unavailable":
        return f"unavailable: {d['detail']}"
    if reason == "collinear":
        with_ = ", ".join(names[j] for j in d["with"]) or "the intercept"
        return f"collinear with {with_} (residual {d['residual']:.1e})"
    if reason == "no_cv_gain":
        return f"no CV gain (CV R^2 {d['cv_r2_with']:.4f} with, {d['cv_r2_without']:.4f} without)"
    raise AssertionError(f"unknown drop reason {reason!r}")


@dataclass
class FitResult:
    """A fitted model of the per-cell luminance difference and its diagnostics.

    ``coefficients`` and ``weights`` cover the kept features (on the Min-Max normalized scale of
    a capture fit, or on the input scale of ``fit_design``); ``weights`` sum to 1, or are all zero
    when every coefficient is zero. ``dropped`` maps each other feature to the reason.
    """

    feature_names: list[str]
    intercept: float
    coefficients: dict[str, float]
    weights: dict[str, float]
    kept: list[str]
    dropped: dict[str, str]
    r2: float
    adjusted_r2: float | None
    cv_r2: float | None
    folds: int
    condition_number: float
    rank: int
    ridge_lambda: float
    n_cells: int
    empty_cells: int = 0
    masked_pixels: int = 0
    cell_px: int | None = None
    feature_min: list[float] | None = None
    feature_max: list[float] | None = None
    light: tuple[str, list[float]] | None = None
    fitted: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False, compare=False)

    @classmethod
    def _from_native(cls, d: Mapping[str, Any], names: Sequence[str], **extra: Any) -> FitResult:
        coef = d["coefficients"]
        weights = d["weights"]
        kept = [names[j] for j in d["kept"]]
        return cls(
            feature_names=list(names),
            intercept=float(d["intercept"]),
            coefficients={names[j]: float(coef[j]) for j in d["kept"]},
            weights={names[j]: float(weights[j]) for j in d["kept"]},
            kept=kept,
            dropped={names[r["index"]]: _reason_text(r, names) for r in d["dropped"]},
            r2=float(d["r2"]),
            adjusted_r2=d["adjusted_r2"],
            cv_r2=d["cv_r2"],
            folds=int(d["folds"]),
            condition_number=float(d["condition_number"]),
            rank=int(d["rank"]),
            ridge_lambda=float(d["ridge_lambda"]),
            n_cells=int(d["n"]),
            fitted=np.asarray(d["fitted"]),
            **extra,
        )

    def __str__(self) -> str:
        def num(v: float | None, fmt: str = ".4f") -> str:
            return "n/a" if v is None else format(v, fmt)

        head = f"vplace fit: {self.n_cells} cells"
        if self.cell_px is not None:
            head += (
                f" of {self.cell_px} px ({self.empty_cells} without geometry excluded,"
                f" {self.masked_pixels} non-finite pixels masked)"
            )
        cv = f"CV R^2 ({self.folds}-fold) {num(self.cv_r2)}" if self.folds else "CV R^2 n/a"
        ridge = f"   ridge lambda {self.ridge_lambda:.2e}" if self.ridge_lambda > 0 else ""
        lines = [
            head,
            f"R^2 {num(self.r2)}   adjusted R^2 {num(self.adjusted_r2)}   {cv}",
            f"condition number {self.condition_number:.3g}   rank {self.rank}{ridge}",
            "",
            f"{'feature':<20} {'coefficient':>14} {'weight':>8}",
            f"{'intercept':<20} {self.intercept:>14.6g} {'':>8}",
        ]
        order = sorted(self.kept, key=lambda n: -self.weights[n])
        lines += [f"{n:<20} {self.coefficients[n]:>14.6g} {self.weights[n]:>8.4f}" for n in order]
        if self.dropped:
            lines += ["", "dropped:"]
            lines += [f"  {n:<20} {why}" for n, why in self.dropped.items()]
        return "\n".join(lines)

    def to_json(self) -> str:
        """The model as JSON (everything but the fitted values)."""
        d = {k: v for k, v in self.__dict__.items() if k != "fitted"}
        cond = d["condition_number"]
        d["condition_number"] = None if math.isinf(cond) else cond
        return json.dumps({"format": _FORMAT, "version": _VERSION, **d}, indent=1)

    @classmethod
    def from_json(cls, text: str) -> FitResult:
        """Loads a model saved by :meth:`to_json`."""
        d = json.loads(text)
        if d.pop("format", None) != _FORMAT or d.pop("version", None) != _VERSION:
            raise _native.InputError(f"not a {_FORMAT} version {_VERSION} document")
        if d["condition_number"] is None:
            d["condition_number"] = math.inf
        if d.get("light") is not None:
            d["light"] = (d["light"][0], d["light"][1])
        return cls(**d)

    def predict_cells(self, values: np.ndarray) -> np.ndarray:
        """The prediction for raw per-cell feature values ``(n, 14)`` (``extract_features``)."""
        if self.feature_min is None or self.feature_max is None:
            raise _native.InputError("this model was fitted on a design matrix; use predict_design")
        lo = np.asarray(self.feature_min)
        hi = np.asarray(self.feature_max)
        rng = hi - lo
        norm = np.where(rng > 0, (values - lo) / np.where(rng > 0, rng, 1.0), 0.0)
        return self.predict_design(norm)

    def predict_design(self, x: np.ndarray) -> np.ndarray:
        """The prediction for rows of the design columns (``(n, len(feature_names))``)."""
        x = np.asarray(x, dtype=np.float64)
        out = np.full(x.shape[0], self.intercept)
        for name, b in self.coefficients.items():
            out += b * x[:, self.feature_names.index(name)]
        return out

    def predict(self, capture: Any, *, light: Any = None) -> np.ndarray:
        """Per-cell predicted luminance difference ``(cells_y, cells_x)`` of another view.

        ``capture`` needs the passes of :func:`fit` except ``gi``. The light defaults to the
        capture's, else the one used for the fit. Cells without geometry get 0.
        """
        lt = _light(capture, light) or self.light
        cells = _native.extract_features(
            **_passes(capture), cell_px=self.cell_px or 16, **_light_kwargs(lt)
        )
        grid = np.zeros(cells["cells_y"] * cells["cells_x"])
        grid[cells["cells"]] = self.predict_cells(cells["values"])
        return grid.reshape(cells["cells_y"], cells["cells_x"])


def extract_features(capture: Any, *, cell_px: int = 16, light: Any = None) -> dict[str, Any]:
    """Per-cell features (and the label when the capture has ``gi``); see
    ``vplace._native.extract_features`` for the keys. Adds ``names``."""
    passes = _passes(capture)
    gi = _get(capture, "gi", required=False)
    if gi is not None:
        passes["gi"] = gi
    out = _native.extract_features(
        **passes, cell_px=cell_px, **_light_kwargs(_light(capture, light))
    )
    out["names"] = list(FEATURE_NAMES)
    return out


def fit(
    capture: Any,
    *,
    cell_px: int = 16,
    light: Any = None,
    folds: int = 5,
    select: bool = True,
    min_cv_gain: float = 1e-3,
    collinear_rtol: float = 1e-6,
    rank_rtol: float | None = None,
    ridge_above: float = 1e6,
) -> FitResult:
    """Fits the per-cell luminance difference of a captured view on its features.

    ``capture``: a mapping or object with float32 arrays ``position``, ``normal``, ``albedo``,
    ``direct``, ``gi`` (H, W, 3), ``depth`` (H, W), bool ``covered`` (H, W), optionally
    ``specular`` (GlossCol, for the reflectance feature), and the light as ``light_position`` or
    ``light_direction`` (3,) or ``lights`` (mappings with ``type``, ``power``, ``position``,
    ``direction``). ``light`` overrides it: ``("position", xyz)``, ``("direction", xyz)`` or a
    mapping with one of those keys. The other settings are those of
    ``vplace_core::regression::FitParams``.
    """
    lt = _light(capture, light)
    cells, model, lo, hi = _native.fit_capture(
        **_passes(capture),
        gi=_get(capture, "gi"),
        **_light_kwargs(lt),
        cell_px=cell_px,
        folds=folds,
        select=select,
        min_cv_gain=min_cv_gain,
        collinear_rtol=collinear_rtol,
        rank_rtol=rank_rtol,
        ridge_above=ridge_above,
    )
    return FitResult._from_native(
        model,
        FEATURE_NAMES,
        empty_cells=int(cells["empty_cells"]),
        masked_pixels=int(cells["masked_pixels"]),
        cell_px=cell_px,
        feature_min=[float(v) for v in lo],
        feature_max=[float(v) for v in hi],
        light=lt,
    )


def fit_design(
    x: np.ndarray,
    y: np.ndarray,
    *,
    names: Sequence[str] | None = None,
    folds: int = 5,
    select: bool = True,
    min_cv_gain: float = 1e-3,
    collinear_rtol: float = 1e-6,
    rank_rtol: float | None = None,
    ridge_above: float = 1e6,
) -> FitResult:
    """Fits ``y`` (n,) on the columns of ``x`` (n, p) with the solver of :func:`fit`.

    ``select=False, collinear_rtol=0, ridge_above=inf`` is plain least squares, as
    ``numpy.linalg.lstsq`` computes it (on standardized columns). NaN or inf is an ``InputError``.
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    y = np.ascontiguousarray(y, dtype=np.float64)
    if x.ndim != 2:
        raise _native.InputError(f"x must have shape (n, p), got {x.shape}")
    names = list(names) if names is not None else [f"x{j}" for j in range(x.shape[1])]
    if len(names) != x.shape[1]:
        raise _native.InputError(f"names: expected {x.shape[1]} names, got {len(names)}")
    d = _native.fit_design(
        x,
        y,
        folds=folds,
        select=select,
        min_cv_gain=min_cv_gain,
        collinear_rtol=collinear_rtol,
        rank_rtol=rank_rtol,
        ridge_above=ridge_above,
    )
    return FitResult._from_native(d, names)
