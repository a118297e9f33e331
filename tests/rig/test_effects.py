"""The effects extension point: registered hooks change the assembly, unknown names fail."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from susp_bo.rig import effects
from susp_bo.rig.assembly import build_assembly
from susp_bo.rig.linear import LinearisedRig
from susp_bo.rig.spec import RigSpec
from susp_bo.rig.state_space import sensor_transfer, state_space


def test_unknown_effect_is_an_error_before_simulation(reference_spec: RigSpec) -> None:
    spec = dataclasses.replace(reference_spec, effects={"no_such_effect": {}})
    with pytest.raises(ValueError, match="no_such_effect"):
        build_assembly(spec)
    disabled = dataclasses.replace(reference_spec, effects={"no_such_effect": {"enabled": False}})
    assert build_assembly(disabled).n_dofs == build_assembly(reference_spec).n_dofs


def test_a_registered_effect_reaches_both_models(
    reference_spec: RigSpec, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(effects, "_REGISTRY", {})

    @effects.register_effect("extra_roll_stiffness")
    def _extra(spec, builder, options) -> None:
        row = np.zeros(builder.n)
        row[builder.bodies["carbody"].dofs[2]] = 1.0
        builder.add_rows(
            "spring",
            "extra_roll",
            row,
            np.zeros(builder.n_inputs),
            stiffness=float(options["stiffness"]),
        )

    spec = dataclasses.replace(reference_spec, effects={"extra_roll_stiffness": {"stiffness": 5e6}})
    assert "extra_roll" in build_assembly(spec).springs.group.names
    base = LinearisedRig(reference_spec).modal_frequencies_hz()["carbody_roll"]
    stiffer = LinearisedRig(spec).modal_frequencies_hz()["carbody_roll"]
    assert stiffer > base * 1.1
    with pytest.raises(ValueError, match="already registered"):
        effects.register_effect("extra_roll_stiffness")(_extra)


def test_modal_and_direct_transfer_functions_agree(reference_spec: RigSpec) -> None:
    system = state_space(build_assembly(reference_spec), 70.0)
    f = np.linspace(0.2, 25.0, 60)
    modal = sensor_transfer(system, f, 100.0)
    direct = sensor_transfer(system, f, 100.0, method="solve")
    np.testing.assert_allclose(modal, direct, rtol=1e-8, atol=1e-10 * np.abs(direct).max())
