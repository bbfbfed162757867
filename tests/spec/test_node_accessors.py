"""The typed accessors that narrow a system's DefineNode | AttachNode | ControlNode union by
type (robotgen.model.system): each returns the node or settings of the kind it names and
raises TypeError, naming the node, for any other kind, so that no caller reads a field off
the union."""

from __future__ import annotations

from pathlib import Path

import pytest

from robotgen.frontend import load_system
from robotgen.model.chain import KinematicTree
from robotgen.model.formula import FormulaRobot
from robotgen.model.laws.force import HybridSettings, ImpedanceSettings
from robotgen.model.laws.hand import AdaptiveSettings
from robotgen.model.laws.resolved_rate import RateControlSettings
from robotgen.model.system import (
    AttachNode,
    ControlNode,
    DefineNode,
    PlanarBody,
    SpatialBody,
    leaf_of,
    under_controls,
)

SPECS = Path(__file__).resolve().parents[2] / "specs"


@pytest.fixture(scope="module")
def styx():
    return load_system(SPECS / "styx_multilevel.yaml")  # ct_hand > hand > ff > fingers > pd_left > left


def test_each_accessor_returns_its_kind_and_refuses_the_others(styx):
    kinds = {DefineNode: styx.define, AttachNode: styx.attach, ControlNode: styx.control}
    for name, node in styx.nodes.items():
        for kind, accessor in kinds.items():
            if isinstance(node, kind):
                assert accessor(name) is node
            else:
                with pytest.raises(TypeError, match=repr(name)):
                    accessor(name)
    assert styx.root_control is styx.nodes["ct_hand"]
    assert isinstance(styx.leaf("left"), FormulaRobot) and isinstance(styx.leaf("box"), (PlanarBody, SpatialBody))
    for name in ("left", "box"):  # a formulas robot and a payload body are no chains
        with pytest.raises(TypeError, match=repr(name)):
            styx.tree(name)
    puma = load_system(SPECS / "puma560_rmrc.yaml")
    assert isinstance(puma.leaf("arm"), KinematicTree) and puma.tree("arm") is puma.define("arm").leaf


def test_under_controls_and_leaf_of_follow_the_tree(styx):
    assert under_controls(styx.nodes, "ct_hand") is styx.nodes["hand"]
    assert under_controls(styx.nodes, "ff") is styx.nodes["fingers"]
    assert under_controls(styx.nodes, "pd_left") is styx.nodes["left"]
    assert under_controls(styx.nodes, "box") is styx.nodes["box"]
    assert leaf_of(styx.nodes["left"]) is styx.define("left").leaf
    assert leaf_of(styx.nodes["hand"]) is None and leaf_of(styx.nodes["pd_left"]) is None and leaf_of(None) is None


@pytest.mark.parametrize(
    "spec, accessor, kind",
    [
        ("puma560_rmac", "adaptive", AdaptiveSettings),
        ("puma560_rmrc", "chain_rate", RateControlSettings),
        ("impedance_arm", "impedance", ImpedanceSettings),
        ("hybrid_arm", "hybrid", HybridSettings),
    ],
)
def test_a_root_law_settings_accessor_narrows_to_its_own(spec, accessor, kind):
    root = load_system(SPECS / f"{spec}.yaml").root_control
    assert isinstance(getattr(root, accessor), kind)
    for other in sorted(
        {"adaptive", "acceleration", "chain_rate", "composite_rate", "impedance", "hybrid"} - {accessor}
    ):
        with pytest.raises(TypeError, match=repr(root.name)):
            getattr(root, other)


def test_a_tree_law_has_no_settings_to_narrow(styx):
    pd = styx.control("pd_left")
    for accessor in ("hand_settings", "rate_settings", "adaptive", "impedance", "hybrid"):
        with pytest.raises(TypeError, match="'pd_left'"):
            getattr(pd, accessor)
