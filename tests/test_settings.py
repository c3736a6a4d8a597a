"""One way to configure a run: reconstruct's keywords, each one field of Settings, or
settings=; the stages' settings validate their own fields."""

import dataclasses
import itertools

import numpy as np
import pytest

import data_tools
import nrsfm
from nrsfm.settings import (
    KEYWORDS,
    METHODS,
    AdmmSettings,
    BilinearSettings,
    MeasurementSettings,
    RotationSettings,
    Settings,
)
from nrsfm.stages.shape import SOLVERS, ShapeResult, solve_shape


@pytest.fixture(scope="module")
def seq():
    return data_tools.make_synthetic(F=30, P=16, K=2, motion="smooth", noise=0.01, seed=2)


def _same(a, b):
    np.testing.assert_array_equal(a.shapes, b.shapes)
    np.testing.assert_array_equal(a.rotations, b.rotations)
    assert a.settings == b.settings


#: each keyword of reconstruct, a value other than its default, and the Settings it means
_KEYWORD_FIELDS = [
    ("method", "bmm", Settings(method="bmm")),
    ("method", "wnn", Settings(method="wnn")),
    ("method", "pseudo_inverse", Settings(method="pseudo_inverse")),
    ("shape_solver", "admm", Settings(shape=AdmmSettings())),
    ("shape_solver", "bilinear", Settings(shape=BilinearSettings())),
    ("missing", "error", Settings(measurement=MeasurementSettings(missing="error"))),
]


def test_every_keyword_is_tested():
    assert {k for k, _, _ in _KEYWORD_FIELDS} == set(KEYWORDS)


@pytest.mark.parametrize("name,value,settings", _KEYWORD_FIELDS)
def test_each_keyword_and_its_settings_field_give_the_same_run(seq, name, value, settings):
    _same(
        nrsfm.reconstruct(seq.W, 2, **{name: value}), nrsfm.reconstruct(seq.W, 2, settings=settings)
    )


def test_the_default_run_is_the_default_settings(seq):
    _same(nrsfm.reconstruct(seq.W, 2), nrsfm.reconstruct(seq.W, 2, settings=Settings()))
    assert Settings().shape == BilinearSettings() and Settings().prior == "organic"


def test_what_each_method_computes(seq):
    for method, m in METHODS.items():
        res = nrsfm.reconstruct(seq.W, 2, method=method)
        assert res.method == method == res.settings.method
        assert res.rotation_stage.n_triplets == (1 if m.single else 2)
        assert res.shape_stage.prior == (m.prior or "none")


@pytest.mark.parametrize(
    "names", [c for n in range(1, len(KEYWORDS) + 1) for c in itertools.combinations(KEYWORDS, n)]
)
def test_keywords_beside_settings_are_refused(seq, names):
    """settings= beside any of the keywords, even at a default value, is a ValueError that
    names them (they would be ignored)."""
    default = dict(method="organic", shape_solver="bilinear", missing="complete")
    with pytest.raises(ValueError, match="settings= replaces") as err:
        nrsfm.reconstruct(seq.W, 2, settings=Settings(), **{n: default[n] for n in names})
    for n in names:
        assert n in str(err.value).split("got ")[1]


def test_settings_must_be_settings(seq):
    with pytest.raises(ValueError, match="nrsfm.Settings"):
        nrsfm.reconstruct(seq.W, 2, settings=dict(method="bmm"))


@pytest.mark.parametrize(
    "make,match",
    [
        (lambda: RotationSettings(delta=-1.0), "delta"),
        (lambda: RotationSettings(hits=1.5), "hits"),
        (lambda: AdmmSettings(lam=1.0), "lam"),
        (lambda: BilinearSettings(max_iter=-1), "max_iter"),
        (lambda: MeasurementSettings(completion="svd"), "completion"),
        (lambda: Settings(method="bogus"), "method"),
        (lambda: Settings(rotation="organic"), "rotation must be a RotationSettings"),
        (lambda: Settings(shape="admm"), "shape must be a BilinearSettings or an AdmmSettings"),
        (lambda: Settings(method="pseudo_inverse", shape=BilinearSettings()), "no shape solver"),
        (lambda: Settings(method="bmm", rotation=RotationSettings(delta=0.1)), "delta"),
        (lambda: Settings.from_keywords(shape_solver="closed_form"), "shape_solver"),
    ],
)
def test_bad_values_are_refused_when_built(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_bmm_takes_the_search_settings():
    assert (
        Settings(method="bmm", rotation=RotationSettings(max_starts=10)).rotation.max_starts == 10
    )


def test_settings_are_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        RotationSettings().delta = 0.2


def test_stage_settings_reach_their_stage(seq):
    s = Settings(
        method="wnn",
        shape=AdmmSettings(N=2, mu=0.5),
        rotation=RotationSettings(max_starts=5, hits=3),
    )
    res = nrsfm.reconstruct(seq.W, 2, settings=s)
    assert res.settings is s and res.settings.shape_solver == "admm"
    assert res.shape_stage.N == 2 and res.shape_stage.params["mu"] == 0.5
    assert res.shape_stage.prior == "weighted"
    assert res.rotation_stage.search.n_starts <= 5


def test_configuration_size():
    """The whole configuration: at most 35 fields over the settings classes."""
    classes = (Settings, MeasurementSettings, RotationSettings, BilinearSettings, AdmmSettings)
    assert sum(len(dataclasses.fields(c)) for c in classes) <= 35


def test_both_solvers_return_the_one_result_type(seq):
    for name, cls in SOLVERS.items():
        res = solve_shape(seq.W, seq.rotations, 2, "organic", cls())
        assert isinstance(res, ShapeResult) and res.solver == name
        assert res.shapes.shape == seq.shapes.shape and np.isfinite(res.objective)
    with pytest.raises(ValueError, match="BilinearSettings or AdmmSettings"):
        solve_shape(seq.W, seq.rotations, 2, "organic", dict(mu=1.0))
    with pytest.raises(ValueError, match="shape prior"):
        solve_shape(seq.W, seq.rotations, 2, "bogus")
