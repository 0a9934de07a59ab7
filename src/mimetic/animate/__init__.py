"""Drivers that produce activations: descriptive controls and the expression library.

``apply_descriptive(rig, {"Smile/Wide": (0.4, 1.0)})`` turns the thesis's descriptive sliders
into channel values; ``blend(rig, [("joy", 0.7), ("surprise", 0.5)])`` turns named expressions
into a pose. Both talk only to the rig's channels (the activation pivot).
"""

from mimetic.animate.controls import (
    ControlError,
    DescriptiveControl,
    apply_descriptive,
    descriptive_control,
    descriptive_controls,
    descriptive_pose,
    read_descriptive,
)
from mimetic.animate.expressions import (
    Expression,
    ExpressionError,
    ExpressionLibrary,
    blend,
    check_library,
    compose_pose,
    expression_pose,
    load_library,
)

__all__ = [
    "ControlError",
    "DescriptiveControl",
    "Expression",
    "ExpressionError",
    "ExpressionLibrary",
    "apply_descriptive",
    "blend",
    "check_library",
    "compose_pose",
    "descriptive_control",
    "descriptive_controls",
    "descriptive_pose",
    "expression_pose",
    "load_library",
    "read_descriptive",
]
