"""`robotgen simulate`: a compiled module closed around a plant.

The plants, one module each: robotgen's own (model_plant.py, with the wall of
wall_contact.py) and MuJoCo's (mujoco/). The simulations: a robot tree's servo step
(tree.py), a multi-rate tree's beside it (multirate.py), and a root law's (a law's
``simulation`` in robotgen.model.laws.registry): a hand controller's (hand.py) and a
resolved-rate regulator's (regulator.py); approach_paths.py runs a resolved-rate module's
position steps as an ideal joint-rate servo."""
