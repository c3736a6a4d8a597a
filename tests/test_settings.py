"""Typed stage settings: presets, dict conversion, validation, dispatch."""

import dataclasses

import numpy as np
import pytest

import data_tools
import nrsfm
from nrsfm.ablation import estimate_rotations_ablation
from nrsfm.settings import (AdmmSettings, BilinearSettings, RotationAblationSettings,
                            RotationSettings, ShapeSettings, method_settings,
                            rotation_settings)
from nrsfm.stages.measurement import measure
from nrsfm.stages.rotations import estimate_rotations
from nrsfm.stages.shape import SOLVERS


@pytest.fixture(scope="module")
def seq():
    return data_tools.make_synthetic(F=30, P=16, K=2, motion="random", seed=2)


def test_presets_of_the_methods():
    s = method_settings("bmm")
    assert s.rotation == RotationSettings.preset("bmm") and s.shape.prior == "nuclear"
    assert method_settings("wnn").shape.prior == "weighted"
    assert method_settings("pseudo_inverse").shape.solver.name == "pseudo_inverse"
    assert method_settings("organic", "admm").shape.solver == AdmmSettings()
    assert isinstance(method_settings().shape.solver, BilinearSettings)


def test_dict_options_become_typed_settings():
    s = method_settings(rotation_options=dict(delta=0.1), shape_options=dict(mu_factor=0.1))
    assert type(s.rotation) is RotationSettings and s.rotation.delta == 0.1
    assert s.shape.solver.mu_factor == 0.1
    s = method_settings(rotation_options=dict(strategy="literal"))
    assert type(s.rotation) is RotationAblationSettings and s.rotation.gram == "nuclear"
    with pytest.raises(ValueError, match="unknown rotation options"):
        method_settings(rotation_options=dict(bogus=1))
    with pytest.raises(ValueError, match="unknown options"):
        method_settings(shape_options=dict(rho0=1.0))           # an ADMM option


@pytest.mark.parametrize("make", [
    lambda: RotationSettings(delta=-1.0), lambda: RotationSettings(strategy="literal"),
    lambda: RotationSettings(hits=1.5), lambda: AdmmSettings(lam=1.0),
    lambda: BilinearSettings(max_iter=-1), lambda: ShapeSettings(prior="bogus"),
    lambda: ShapeSettings(solver="bilinear"), lambda: ShapeSettings(prior=None),
])
def test_bad_values_are_refused_when_built(make):
    with pytest.raises(ValueError):
        make()


def test_settings_are_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        RotationSettings().delta = 0.2


def test_rotation_strategy_through_reconstruct(seq):
    """The issue's TypeError: reconstruct(W, K, rotation_options=dict(strategy="bmm"))."""
    a = nrsfm.reconstruct(seq.W, 2, rotation_options=dict(strategy="bmm"))
    b = nrsfm.reconstruct(seq.W, 2, method="bmm")
    np.testing.assert_array_equal(a.rotations, b.rotations)
    assert a.params["settings"].rotation.strategy == "bmm"


def test_typed_settings_equal_the_dict_form(seq):
    s = method_settings("organic", "admm", shape_options=dict(N=2))
    a = nrsfm.reconstruct(seq.W, 2, settings=s)
    b = nrsfm.reconstruct(seq.W, 2, shape_solver="admm", shape_options=dict(N=2))
    np.testing.assert_array_equal(a.shapes, b.shapes)
    assert a.shape_stage.N == 2 and a.shape_stage.solver == "admm"


def test_production_and_ablation_rotation_stage_agree(seq):
    M = measure(seq.W, 2).factorization.M_hat
    a = estimate_rotations(M, 2, RotationSettings(), seed=0)
    b = estimate_rotations_ablation(M, 2, RotationSettings(), seed=0)
    np.testing.assert_array_equal(a.rotations, b.rotations)
    with pytest.raises(ValueError, match="ablation"):
        estimate_rotations(M, 2, rotation_settings("windows"))


def test_every_registered_solver_returns_the_one_result_type(seq):
    for name, solver in SOLVERS.items():
        prior = None if name in ("closed_form", "pseudo_inverse") else "organic"
        res = nrsfm.stages.shape.solve_shape(seq.W, seq.rotations, 2,
                                             ShapeSettings(prior, solver.settings()))
        assert isinstance(res, nrsfm.stages.shape.ShapeResult) and res.solver == name
        assert res.shapes.shape == seq.shapes.shape and np.isfinite(res.objective)
