"""Rigs: the ``Rig`` data model, its consistency checks and the ``.mrig`` file format.

``Rig`` holds a rest mesh with muscles, wires, bones, skin weights, regions, landmarks and the
named channels of the activation pivot. ``save_rig`` / ``load_rig`` write and read it losslessly.
"""

from mimetic.rig.format import FORMAT_VERSION, load_rig, save_rig
from mimetic.rig.model import (
    Bone,
    Channel,
    Muscle,
    Rig,
    Wire,
    rig_differences,
    rigs_equal,
)
from mimetic.rig.validate import validate_rig

__all__ = [
    "FORMAT_VERSION",
    "Bone",
    "Channel",
    "Muscle",
    "Rig",
    "Wire",
    "load_rig",
    "rig_differences",
    "rigs_equal",
    "save_rig",
    "validate_rig",
]
