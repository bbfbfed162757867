"""The law registry (robotgen.model.laws.registry): every law's named parts exist, are of the
kind its floor expects, and agree with the descriptor's flags."""

from __future__ import annotations

import pytest

from robotgen.model.laws.registry import LAWS, root_laws, tree_laws
from robotgen.symbolic.control.law import TreeLaw, expected_start, reads_no_forces
from robotgen.symbolic.root_laws.law import RootLaw

SIMULATION_ENTRIES = ("refusal", "comparison_system", "simulate", "write_csv", "plot", "summary", "compare")


@pytest.mark.parametrize("name", list(LAWS))
def test_every_part_a_law_names_exists(name):
    law = LAWS[name]
    kernels = law.part("kernels")
    assert isinstance(kernels, RootLaw if law.is_root else TreeLaw)
    assert kernels.name == name
    assert (law.settings is None) == (law.schema is None), "a settings block has a reader and a schema"
    if law.settings is not None:
        assert callable(law.part("settings"))
        schema = law.part("schema")
        assert schema["type"] == "object" and schema["additionalProperties"] is False
    if law.is_root:  # a root law makes the module itself: its settings, its own simulation
        assert law.settings is not None and not law.gains
        simulation = law.part("simulation")
        assert all(callable(getattr(simulation, entry)) for entry in SIMULATION_ENTRIES)
    else:
        assert law.simulation is None and not law.hand_frame


@pytest.mark.parametrize("name", tree_laws())
def test_a_tree_laws_flags_agree_with_its_kernels(name):
    law, kernels = LAWS[name], LAWS[name].part("kernels")
    assert law.stateful == kernels.stateful
    assert law.expected == (kernels.state is expected_start)  # what `anchor` applies to
    assert law.reads_forces == (kernels.reads_forces is not reads_no_forces)
    assert law.internal_forces == (not kernels.transparent)  # a transparent law passes everything up
    assert law.gains == (law.no_gains == "")


def test_the_tables_order_is_the_laws_order():
    assert tree_laws() == ("computed_torque", "feedforward", "pd_feedforward", "pd", "impedance", "hybrid")
    assert root_laws() == ("resolved_rate", "resolved_acceleration", "resolved_adaptive")
    assert [LAWS[n].hand_frame for n in root_laws()] == [False, True, True]


def test_a_part_that_is_missing_fails_by_name():
    law = LAWS["pd"]
    assert law.part("settings") is None
    broken = type(law)("broken", "robotgen.symbolic.control.pd:NO_SUCH_LAW")
    with pytest.raises(AttributeError, match="NO_SUCH_LAW"):
        broken.part("kernels")
