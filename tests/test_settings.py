"""Typed stage settings: presets, dict conversion, validation, dispatch, the settings= guard
and the solver registry."""

import dataclasses
import itertools
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

import data_tools
import nrsfm
from nrsfm.research import RotationAblationSettings, research_settings, rotation_settings
from nrsfm.research.rotations import estimate_rotations_ablation
from nrsfm.settings import (METHODS, AdmmSettings, BilinearSettings, ClosedFormSettings,
                            MeasurementSettings, RotationSettings, Settings, ShapeSettings,
                            method_settings)
from nrsfm.stages.measurement import measure
from nrsfm.stages.rotations import estimate_rotations
from nrsfm.stages.shape import SOLVERS, ShapeResult, SolverSettings, solve_shape
from nrsfm.stages.shape.pseudo_inverse import PseudoInverseSettings


@pytest.fixture(scope="module")
def seq():
    return data_tools.make_synthetic(F=30, P=16, K=2, motion="smooth", seed=2)


def test_presets_of_the_methods():
    s = method_settings("bmm")
    assert s.rotation == RotationSettings.preset("bmm") and s.shape.prior == "nuclear"
    assert method_settings("wnn").shape.prior == "weighted"
    assert method_settings("pseudo_inverse").shape.solver.name == "pseudo_inverse"
    assert method_settings("organic", "admm").shape.solver == AdmmSettings()
    assert isinstance(method_settings().shape.solver, BilinearSettings)
    for method in METHODS:                 # the typed preset is the dict form's
        assert Settings(method=method) == method_settings(method) == Settings.preset(method)


def test_method_is_a_preset_not_a_label():
    """The issue's case: Settings(method="bmm") is the BMM baseline."""
    s = Settings(method="bmm")
    assert s.rotation.strategy == "bmm" and s.shape.prior == "nuclear"
    assert Settings().method == "organic" and Settings().shape.prior == "organic"
    with pytest.raises(ValueError, match="rotation strategy 'organic'"):
        Settings(method="bmm", rotation=RotationSettings())
    with pytest.raises(ValueError, match="shape prior 'organic'"):
        Settings(method="bmm", shape=ShapeSettings())
    with pytest.raises(ValueError, match="shape solver 'bilinear'"):
        Settings(method="pseudo_inverse", shape=ShapeSettings())
    with pytest.raises(ValueError, match="method"):
        Settings(method="bogus")
    # composed freely: the label is the preset the stages agree with, or "custom"
    assert Settings(rotation=RotationSettings.preset("bmm"),
                    shape=ShapeSettings(prior="nuclear")).method == "bmm"
    assert Settings(rotation=RotationSettings.preset("bmm")).method == "custom"
    assert research_settings("family").method == "custom"
    # a prior-free solver may replace the method's prior
    cf = Settings(method="organic", shape=ShapeSettings(prior=None, solver=ClosedFormSettings()))
    assert cf.method == "organic" and cf.shape.prior is None


def test_dict_options_become_typed_settings():
    s = method_settings(rotation_options=dict(delta=0.1), shape_options=dict(mu_factor=0.1))
    assert type(s.rotation) is RotationSettings and s.rotation.delta == 0.1
    assert s.shape.solver.mu_factor == 0.1
    with pytest.raises(ValueError, match="unknown rotation options"):
        method_settings(rotation_options=dict(bogus=1))
    with pytest.raises(ValueError, match="unknown rotation options"):
        method_settings(rotation_options=dict(gram="nuclear"))       # a research option
    with pytest.raises(ValueError, match="fixes the strategy"):
        method_settings(rotation_options=dict(strategy="bmm"))
    with pytest.raises(ValueError, match="unknown options"):
        method_settings(shape_options=dict(rho0=1.0))           # an ADMM option
    with pytest.raises(ValueError, match="its own shape solver"):
        method_settings("pseudo_inverse", "admm")
    with pytest.raises(ValueError, match="its own shape solver"):
        method_settings("pseudo_inverse", shape_options=dict(mu=1.0))
    assert method_settings(rotation_options=dict(strategy="organic")) == method_settings()


@pytest.mark.parametrize("make", [
    lambda: RotationSettings(delta=-1.0), lambda: RotationSettings(strategy="literal"),
    lambda: RotationSettings(hits=1.5), lambda: AdmmSettings(lam=1.0),
    lambda: BilinearSettings(max_iter=-1), lambda: ShapeSettings(prior="bogus"),
    lambda: ShapeSettings(solver="bilinear"), lambda: ShapeSettings(prior=None),
    lambda: ShapeSettings(prior="organic", solver=ClosedFormSettings()),
    lambda: Settings(rotation="organic"), lambda: MeasurementSettings(completion="svd"),
])
def test_bad_values_are_refused_when_built(make):
    with pytest.raises(ValueError):
        make()


def test_settings_are_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        RotationSettings().delta = 0.2


def test_method_bmm_through_reconstruct_is_bmm(seq):
    """The issue's case: settings=Settings(method="bmm") runs BMM, as method="bmm" does."""
    a = nrsfm.reconstruct(seq.W, 2, settings=Settings(method="bmm"))
    b = nrsfm.reconstruct(seq.W, 2, method="bmm")
    np.testing.assert_array_equal(a.shapes, b.shapes)
    assert a.method == "bmm" and a.rotation_stage.strategy == "bmm"
    assert a.params["shape_prior"] == "nuclear" == a.shape_stage.prior


#: every keyword that settings= replaces, with a value that differs from its default
_BESIDE = dict(method="bmm", shape_solver="admm", missing="error",
               rotation_options=dict(delta=0.1), shape_options=dict(mu_factor=0.5))


@pytest.mark.parametrize("names", [c for n in range(1, len(_BESIDE) + 1)
                                   for c in itertools.combinations(_BESIDE, n)])
def test_options_beside_settings_are_refused(seq, names):
    """Every combination of settings= with the keywords it replaces is a ValueError that
    names them (the issue's case: settings=Settings(), shape_options=...)."""
    with pytest.raises(ValueError, match="settings= replaces") as err:
        nrsfm.reconstruct(seq.W, 2, settings=Settings(), **{n: _BESIDE[n] for n in names})
    for n in names:
        assert n in str(err.value).split("got ")[1]


@pytest.mark.parametrize("name", list(_BESIDE))
def test_defaults_beside_settings_are_refused_too(seq, name):
    """Even a keyword at its documented default is refused beside settings= (it would be
    ignored if the settings said otherwise)."""
    default = dict(method="organic", shape_solver="bilinear", missing="complete",
                   rotation_options={}, shape_options={})[name]
    with pytest.raises(ValueError, match=name):
        nrsfm.reconstruct(seq.W, 2, settings=Settings(method="bmm"), **{name: default})


def test_settings_must_be_settings(seq):
    with pytest.raises(ValueError, match="nrsfm.settings.Settings"):
        nrsfm.reconstruct(seq.W, 2, settings=dict(method="bmm"))


def test_params_are_the_settings_that_ran(seq):
    s = Settings(method="wnn", shape=ShapeSettings(prior="weighted",
                                                   solver=AdmmSettings(mu=0.5)))
    res = nrsfm.reconstruct(seq.W, 2, settings=s)
    p = res.params
    assert p["settings"] == s and p["method"] == "wnn" == res.method
    assert p["shape_prior"] == "weighted" == res.shape_stage.prior
    assert p["shape_solver"] == "admm" and p["shape_options"]["mu"] == 0.5
    assert p["rotation_strategy"] == "organic"
    assert p["rotation_options"] == dataclasses.asdict(s.rotation)
    given = nrsfm.reconstruct(seq.W, 2, rotations=seq.rotations, method="bmm")
    assert given.params["rotation_strategy"] is None and given.params["rotations_given"]
    assert given.params["shape_prior"] == "nuclear"


def test_typed_settings_equal_the_dict_form(seq):
    s = method_settings("organic", "admm", shape_options=dict(N=2))
    a = nrsfm.reconstruct(seq.W, 2, settings=s)
    b = nrsfm.reconstruct(seq.W, 2, shape_solver="admm", shape_options=dict(N=2))
    np.testing.assert_array_equal(a.shapes, b.shapes)
    assert a.shape_stage.N == 2 and a.shape_stage.solver == "admm"


def test_production_and_research_rotation_stage_agree(seq):
    M = measure(seq.W, 2).factorization.M_hat
    a = estimate_rotations(M, 2, RotationSettings(), seed=0)
    b = estimate_rotations_ablation(M, 2, RotationSettings(), seed=0)
    np.testing.assert_array_equal(a.rotations, b.rotations)
    c = estimate_rotations(M, 2, rotation_settings("windows"))      # research settings run
    assert c.strategy == "windows" and isinstance(rotation_settings("windows"),
                                                  RotationAblationSettings)
    with pytest.raises(ValueError, match="RotationSettings"):
        estimate_rotations(M, 2, "organic")


def test_research_strategy_through_reconstruct(seq):
    res = nrsfm.reconstruct(seq.W, 2, settings=research_settings("literal"))
    assert res.method == "custom" and res.rotation_stage.strategy == "literal"
    assert res.params["rotation_strategy"] == "literal"


def test_every_registered_solver_returns_the_one_result_type(seq):
    for name, cls in SOLVERS.items():
        prior = "organic" if cls.uses_prior else None
        res = solve_shape(seq.W, seq.rotations, 2, ShapeSettings(prior, cls()))
        assert isinstance(res, ShapeResult) and res.solver == name
        assert res.shapes.shape == seq.shapes.shape and np.isfinite(res.objective)


def test_a_new_solver_is_one_module(seq):
    """A solver defined here, outside the package, registers itself and runs through
    reconstruct, the dict form and the CLI's choice list (the registry)."""

    @dataclass(frozen=True)
    class ToySettings(SolverSettings):
        name: ClassVar[str] = "toy"
        uses_prior: ClassVar[bool] = False
        scale: float = 1.0

        def solve(self, W, R, K, prior, progress=None, observed=None):
            base = PseudoInverseSettings().solve(W, R, K)
            return dataclasses.replace(base, shapes=self.scale * base.shapes, solver="toy")

    try:
        assert SOLVERS["toy"] is ToySettings
        res = nrsfm.reconstruct(seq.W, 2, rotations=seq.rotations, shape_solver="toy",
                                shape_options=dict(scale=1.0))
        ref = nrsfm.reconstruct(seq.W, 2, rotations=seq.rotations, method="pseudo_inverse")
        np.testing.assert_allclose(res.shapes, ref.shapes)
        assert res.params["shape_solver"] == "toy" and res.params["shape_prior"] is None
        with pytest.raises(ValueError, match="registered already"):
            type("Other", (SolverSettings,), {"name": "toy"})
    finally:
        SOLVERS.pop("toy", None)
    with pytest.raises(ValueError, match="toy"):
        method_settings(shape_solver="toy")
