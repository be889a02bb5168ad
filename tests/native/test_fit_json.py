"""Saved models (issue 19): every model JSON written before the serde move still loads, predicts
the same and saves back to the same JSON object."""

import json
from pathlib import Path

import numpy as np
import vplace
from vplace.bench_fit import synthetic_capture, synthetic_view

DATA = Path(__file__).parent / "data"


def test_a_saved_view_model_loads_and_predicts_the_same():
    text = (DATA / "fit_v3_views.json").read_text()
    model = vplace.Fit.from_json(text)
    view = synthetic_view(synthetic_capture(64, 48))
    assert np.array_equal(model.predict(view), np.load(DATA / "fit_v3_views_predict.npy"))
    assert json.loads(model.to_json()) == json.loads(text)


def test_a_saved_design_model_loads_and_predicts_the_same():
    text = (DATA / "fit_v3_design.json").read_text()
    model = vplace.Fit.from_json(text)
    x = np.load(DATA / "fit_v3_design_x.npy")
    assert np.array_equal(model.predict_design(x), np.load(DATA / "fit_v3_design_predict.npy"))
    assert json.loads(model.to_json()) == json.loads(text)
