"""The report's configuration (the scene presets, ``ReportConfig``) and its rows (``Row``,
as CSV and JSON)."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from .. import job as pipeline
from ..errors import AddonError, ReportError
from ..native import vplace
from ..scenes import lroom
from ..scenes import registry as default_scene
from ..scenes import rooms as builtin_rooms
from ..writeback import apply, eevee_setup
from ..writeback import eevee_render as eevee

#: Seeds of the renders: the user's capture, the ground truth, Cycles' curve.
CAPTURE_SEED = 0
TRUTH_SEED = 7919
#: The second render of every view's truth (``ReportConfig.truth_noise``).
OTHER_TRUTH_SEED = pipeline.OTHER_REFERENCE_SEED
CURVE_SEED = 104729

METHODS = pipeline.METHODS
RELAYOUT = "vplace (re-layout)"
#: vplace+refit laid out from captures at other sample counts (``samples``: the capture's spp).
CAPTURE_CURVE = "vplace+refit by capture spp"
#: The suffix of a VPL method rendered with EEVEE's ray-traced reflections on.
WITH_RT = " + rt reflections"
#: The budget the image grids, EEVEE and the targets use (the nearest one run).
GRID_BUDGET = 256
#: The issues' margins: vplace's SSIM above each baseline, EEVEE with VPLs above EEVEE's own GI,
#: held-out views against the fit views' mean, EEVEE against the evaluator.
SSIM_MARGIN = 0.05
HELD_OUT_SPREAD = 0.03
#: Issue 20: the one-time cost for one camera's region at most this many Cycles + OIDN frames
#: of that camera at this many samples, the same size.
COST_FRAMES = 2
#: The set-ups the report renders on every run rather than reading from its cache: the cost
#: check sets their frames against the captures, which are rendered on every run too, so both
#: sides are timed on the machine as it is now.
UNCACHED = frozenset({"cycles+oidn"})
#: Issue 21: EEVEE's RMSE at most this many times the evaluator's for the same lights, and at
#: most this share of hot-spot pixels (``vplace.job.outliers``).
EEVEE_RMSE_RATIO = 1.25
HOT_SHARE = 0.001
COST_SAMPLES = pipeline.COST_SAMPLES
EEVEE_SPREAD = 0.02
BRIGHTNESS_TOLERANCE = 0.03
FIT_VIEW_SSIM = 0.90
#: The default capture's layout against the curve's largest sample count.
CAPTURE_SPREAD = 0.01
#: Held-out views made around the fit camera of a scene that names none, and the most allowed.
GENERATED_VIEWS = 2
MAX_GENERATED = 8
#: The name of a made held-out view's camera (removed when the scene's report is done).
GENERATED_PREFIX = "vplace held-out "
#: The largest clip start of a made held-out view's camera, metres: it stands where its fit
#: camera's view begins (past that camera's clip start), so a clip start that let the fit camera
#: see through a wall would let it see out of the room.
GENERATED_CLIP_START = 0.1


@dataclass(frozen=True)
class ScenePreset:
    """A scene for the report: its views, capture size and sample counts."""

    name: str
    fit_views: tuple[str, ...]
    held_out_views: tuple[str, ...]
    resolution: tuple[int, int]
    #: The fit views' capture: every built-in scene at the main job's (``Job.samples``), so
    #: that the report scores the lights a user gets and the one-time cost a user pays
    #: (``--capture-samples`` and ``--capture-curve`` for more).
    capture_samples: int
    truth_samples: int
    #: A .blend path, or None for the built-in scene of this name.
    blend: Path | None = None


PRESETS = {
    "cornell": ScenePreset(
        "cornell",
        ("Cornell camera", "Cornell camera left", "Cornell camera high"),
        (default_scene.CORNELL_HELD_OUT_CAMERA, "Cornell camera (held out, low)"),
        (160, 160),
        pipeline.Job.samples,
        2048,
    ),
    "sponza": ScenePreset(
        "sponza",
        (default_scene.SPONZA_CAMERA, "CameraBalcony", default_scene.SPONZA_WEST_CAMERA),
        (default_scene.SPONZA_HELD_OUT_CAMERA, "CameraAlcove"),
        (320, 180),
        pipeline.Job.samples,
        1024,
    ),
    "skyroom": ScenePreset(
        "skyroom",
        tuple(builtin_rooms.SKYROOM_FIT),
        tuple(builtin_rooms.SKYROOM_HELD_OUT),
        (256, 144),
        pipeline.Job.samples,
        1024,
    ),
    "lroom": ScenePreset(
        "lroom",
        tuple(lroom.LROOM_FIT),
        tuple(lroom.LROOM_HELD_OUT),
        (192, 108),
        pipeline.Job.samples,
        1024,
    ),
    "panelroom": ScenePreset(
        "panelroom",
        tuple(builtin_rooms.PANELROOM_FIT),
        tuple(builtin_rooms.PANELROOM_HELD_OUT),
        (256, 144),
        pipeline.Job.samples,
        1024,
    ),
}


@dataclass
class ReportConfig:
    """What the report runs. ``None`` fields take the scene preset's value."""

    scenes: Sequence[str] = ("cornell", "sponza", "skyroom", "panelroom", "lroom")
    #: Any .blend instead of the built-in scenes, with its cameras.
    blend: Path | None = None
    fit_cameras: Sequence[str] = ()
    held_out_cameras: Sequence[str] = ()
    budgets: Sequence[int] = (16, 64, 256, 1024)
    methods: Sequence[str] = METHODS
    resolution: tuple[int, int] | None = None
    capture_samples: int | None = None
    truth_samples: int | None = None
    #: Cycles + OpenImageDenoise at these samples, the user's alternative.
    cycles_samples: Sequence[int] = (1, 4, 16, 64)
    alpha: float = 1.0
    iterations: int = 3
    cell_px: int = 16
    #: One of :data:`pipeline.FEATURE_MODES`.
    feature_mode: str = "auto"
    #: Let the captures give the regression-guided sets the near-field gather
    #: (``Job.near_field``); False: never.
    near_field: bool = True
    #: Seeds of the stochastic layouts (uniform, vplace); tables and plots show their mean.
    seeds: Sequence[int] = (0, 1, 2)
    #: Score the grid budget's lights with EEVEE, beside EEVEE's own GI.
    with_eevee: bool = True
    #: The methods whose lights EEVEE renders (each costs one EEVEE render per view).
    eevee_methods: Sequence[str] = ("uniform", "rsm", "vplace+refit")
    #: The alternatives of :data:`eevee.SETUPS` rendered per view (``cycles+oidn`` runs at
    #: ``cycles_samples``).
    alternatives: Sequence[str] = ("plain", "rt", "rt+volume", "vpl+rt", "cycles+oidn")
    eevee_samples: int = eevee.EEVEE_SAMPLES
    #: The views EEVEE renders, by name as the report names them (a fit or held-out camera's
    #: name, ``vplace held-out 1``); empty: every view. EEVEE without a GPU takes 12-25 minutes
    #: a Sponza frame with 256 VPLs (docs/EEVEE_NOTES.md): this keeps a check to the views it
    #: is about.
    eevee_views: Sequence[str] = ()
    #: Capture sample counts to lay out vplace+refit from (at the grid budget), every view
    #: scored: layout quality against capture cost. Empty: no curve.
    capture_curve: Sequence[int] = ()
    #: Probes along the longest side of the baked light probe volumes (``rt+volume``, and the
    #: world's volume of the VPL renders when the world emits).
    volume_resolution: int = eevee_setup.VOLUME_PROBES
    par2d: bool = True
    #: Where the truths and EEVEE's renders are cached (default ``OUT/cache``); what the
    #: one-time cost and the cost check time is rendered on every run (:data:`UNCACHED`).
    cache_dir: Path | None = None
    #: Coverage views of the region around the fit cameras (``vplace.coverage``).
    coverage: int = vplace.coverage.DEFAULT_COUNT
    region_radius: float = 0.0
    #: Render the coverage views with Cycles and fit them as captures (``ViewSet.render_coverage``).
    render_coverage: bool = True
    #: Held-out views made in the region around the first fit camera (``vplace.coverage.
    #: held_out_poses``): None, :data:`GENERATED_VIEWS` where the scene names no held-out
    #: camera (so every run scores views the lights were not laid out for), else none.
    generated_views: int | None = None
    #: Render every view's truth a second time with another seed (:data:`OTHER_TRUTH_SEED`), so
    #: that each row also has its SSIM against the noise-free truth, and each view the ceiling
    #: the truth's own noise puts on SSIM (``vplace.ssim_noise_free``, ``vplace.ssim_ceiling``).
    truth_noise: bool = True
    #: The VPLs' near-field radius, metres (``Job.radius``); None: 1 % of the scene's diagonal.
    radius: float | None = None
    #: Lay out ``vplace+refit`` as ``demo --match-eevee`` does (``Job.match_eevee``: "auto",
    #: "on" or "off"; ``writeback.match_eevee``): the refit fits what EEVEE's direct light
    #: lacks on each captured view as well, where that helps; the EEVEE renders that takes
    #: count in the one-time cost (rendered on every run, never read from the cache).
    match_eevee: str = "auto"

    def generated_for(self, preset: ScenePreset) -> int:
        """How many held-out views the report makes for ``preset``."""
        if self.generated_views is not None:
            return self.generated_views
        return 0 if preset.held_out_views else GENERATED_VIEWS

    def presets(self) -> list[ScenePreset]:
        """The scenes to run. A .blend is named after its file and captured at the main job's
        samples (``Job.samples``, as the demo and the panel capture)."""
        if self.blend is not None:
            return [
                ScenePreset(
                    Path(self.blend).stem,
                    tuple(self.fit_cameras),
                    tuple(self.held_out_cameras),
                    self.resolution or (320, 180),
                    self.capture_samples or pipeline.Job.samples,
                    self.truth_samples or 1024,
                    blend=Path(self.blend),
                )
            ]
        return [PRESETS[s] for s in self.scenes]

    def validate(self) -> None:
        """Raises :class:`ReportError` for an unusable configuration."""
        try:
            vplace.coverage.Region(self.coverage, self.region_radius).validate()
        except ValueError as err:
            raise ReportError(str(err)) from None
        if self.generated_views is not None and not 0 <= self.generated_views <= MAX_GENERATED:
            raise ReportError(
                f"generated views must be 0 to {MAX_GENERATED}, got {self.generated_views}"
            )
        unknown = [m for m in self.methods if m not in METHODS]
        if unknown:
            raise ReportError(f"unknown methods {unknown}: choose from {list(METHODS)}")
        try:
            pipeline.Job(radius=self.radius).validate()  # the job's own check of the radius
        except AddonError as exc:
            raise ReportError(str(exc)) from None
        if not self.budgets or min(self.budgets) < 1:
            raise ReportError(f"budgets must be positive VPL counts, got {list(self.budgets)}")
        if max(self.budgets) > apply.MAX_VPLS:
            raise ReportError(f"budgets above {apply.MAX_VPLS} VPLs are not supported")
        if self.blend is not None:
            try:
                default_scene.check_blend(Path(self.blend))
            except AddonError as exc:
                raise ReportError(str(exc)) from exc
            if not self.fit_cameras:
                raise ReportError(
                    "a report on a .blend needs --fit-cameras: the cameras to lay the lights out "
                    "for (e.g. the scene camera's name)"
                )
        else:
            bad = [s for s in self.scenes if s not in PRESETS]
            if bad:
                raise ReportError(f"unknown scenes {bad}: choose from {sorted(PRESETS)}")
        if any(s < 1 for s in (*self.cycles_samples, *self.capture_curve)):
            raise ReportError("Cycles sample counts must be at least 1")
        for name, value in (
            ("capture samples", self.capture_samples),
            ("truth samples", self.truth_samples),
            ("EEVEE samples", self.eevee_samples),
        ):
            if value is not None and value < 1:
                raise ReportError(f"{name} must be at least 1, got {value}")
        if self.resolution is not None and min(self.resolution) < 8:
            raise ReportError(f"the resolution must be at least 8 x 8, got {list(self.resolution)}")
        if not 0.0 <= self.alpha <= 1.0:
            raise ReportError(
                f"alpha must be 0 (uniform) to 1 (regression-guided), got {self.alpha}"
            )
        if self.iterations < 0:
            raise ReportError(f"layout iterations must be 0 (off) or more, got {self.iterations}")
        if self.feature_mode not in pipeline.FEATURE_MODES:
            raise ReportError(f"feature mode must be one of {pipeline.FEATURE_MODES}")
        if self.volume_resolution < 1:
            raise ReportError("the light probe volume needs at least 1 probe along each side")
        if not self.seeds:
            raise ReportError("give at least one seed")
        bad = [a for a in self.alternatives if a not in eevee.SETUPS]
        if bad:
            raise ReportError(f"unknown alternatives {bad}: choose from {sorted(eevee.SETUPS)}")
        bad = [m for m in self.eevee_methods if m not in METHODS]
        if bad:
            raise ReportError(f"unknown EEVEE methods {bad}: choose from {list(METHODS)}")


@dataclass
class RowDetails:
    """What only some rows have (None where a row has not): written as the row's ``extra``."""

    #: EEVEE rows: the set-up (``eevee.SETUPS``), and a probe volume's bake.
    setup: str | None = None
    bake_seconds: float | None = None
    #: Capture-curve rows: the captures' seconds.
    capture_seconds: float | None = None
    #: Re-layout rows: per kept feature, where the view's cells lie outside the fit's range.
    out_of_range: dict[str, float] | None = None
    #: Regression-guided layouts: the iteration's errors, its best, the reused shadow rays.
    iteration_errors: list[float] | None = None
    best_iteration: int | None = None
    shared_pixels: int | None = None
    #: Refitted layouts.
    refit_seconds: float | None = None
    refit_error_before: float | None = None
    refit_error_after: float | None = None
    #: The refit's ridge (chosen by cross-validation: one captured view left out at a time with
    #: three or more captures, else blocks of the captured pixels).
    refit_ridge: float | None = None
    #: What the refit pulled the powers toward, as a multiple of the light-path powers: 1, or
    #: the captures' gain where the cross-validation took it.
    refit_gain: float | None = None
    switched_off: int | None = None
    #: Regression-guided layouts: whether their light includes the near-field gather
    #: (``vplace.job.choose_near_field``), and the captures' luminance RMSE without and with it.
    near_field: bool | None = None
    near_field_without: float | None = None
    near_field_with: float | None = None
    #: vplace+refit with ``--match-eevee``: whether the refit kept EEVEE's direct-light deficit,
    #: and EEVEE's predicted RMSE on the matched views with and without (``MatchChoice``).
    eevee_match: dict[str, Any] | None = None
    #: vplace+refit where the match ran: the seconds of its EEVEE renders (in the one-time cost).
    match_seconds: float | None = None
    #: EEVEE rows of written VPLs: where EEVEE's error comes from (``vplace.job.Attribution``).
    attribution: dict[str, Any] | None = None
    #: Rows averaged over seeds (``summary.aggregate``): how many, each seed's scores, spreads.
    seeds: int | None = None
    by_seed: dict[str, dict[str, float]] | None = None
    ssim_std: float | None = None
    rmse_std: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """The details a row has, JSON-ready."""
        return {k: v for k, v in asdict(self).items() if v is not None}


@dataclass
class Row:
    """One scored image: a method (or an alternative) at a budget on a view, by a renderer."""

    scene: str
    view: str
    role: str  # "fit" or "held-out"
    method: str  # a METHODS name, RELAYOUT, an eevee.SETUPS name, or "direct"
    renderer: str  # "evaluator", "eevee", "cycles" or "reference"
    n_vpls: int | None
    samples: int | None
    rmse: float
    relative_mse: float
    ssim: float
    #: Mean luminance of the image over the ground truth's.
    brightness: float
    #: Paid once for every frame and view: captures, fit, layout, refit, a volume's bake.
    one_time_seconds: float
    #: One frame: the evaluator's image, an EEVEE or a Cycles render.
    frame_seconds: float
    #: ``vplace.job.outliers``: the share of hot-spot pixels and of the squared error in the
    #: worst 1 % of pixels.
    hot_pixels: float = math.nan
    worst_share: float = math.nan
    shadow_rays: int = 0
    seed: int | None = None
    details: RowDetails = field(default_factory=lambda: RowDetails())
    #: SSIM against the noise-free truth, estimated from the view's two truth renders
    #: (``vplace.ssim_noise_free``); NaN without the second (``ReportConfig.truth_noise``).
    ssim_noise_free: float = math.nan
    #: RMSE against the noise-free truth (``vplace.rmse_noise_free``); NaN without the second.
    rmse_noise_free: float = math.nan

    @property
    def one_minus_ssim(self) -> float:
        return 1.0 - self.ssim


def row_dict(row: Row) -> dict[str, Any]:
    """A row as a flat JSON-ready dict (its details kept nested as ``extra``)."""
    d = asdict(row)
    del d["details"]
    d["extra"] = row.details.to_dict()
    d["one_minus_ssim"] = row.one_minus_ssim
    return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in d.items()}


CSV_FIELDS = (
    "scene",
    "view",
    "role",
    "method",
    "renderer",
    "n_vpls",
    "samples",
    "rmse",
    "relative_mse",
    "ssim",
    "one_minus_ssim",
    "ssim_noise_free",
    "rmse_noise_free",
    "brightness",
    "hot_pixels",
    "worst_share",
    "one_time_seconds",
    "frame_seconds",
    "shadow_rays",
    "seed",
)


def write_csv(path: Path, rows: list[Row]) -> None:
    """The rows as CSV (without ``extra``)."""
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(row_dict(r))


def grid_budget(budgets: Sequence[int]) -> int:
    """The budget nearest GRID_BUDGET (the lower one on ties): image grids, EEVEE, targets."""
    return min(budgets, key=lambda n: (abs(n - GRID_BUDGET), n))
