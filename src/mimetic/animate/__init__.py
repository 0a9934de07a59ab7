"""Drivers that produce activations: descriptive controls, the expression library, FACS, ARKit-52
and MPEG-4 control layers, and keyframed clips.

``apply_descriptive(rig, {"Smile/Wide": (0.4, 1.0)})`` turns the thesis's descriptive sliders
into channel values; ``blend(rig, [("joy", 0.7), ("surprise", 0.5)])`` turns named expressions
into a pose; ``mimetic.animate.facs``, ``.arkit`` and ``.mpeg4`` do the same for action units,
ARKit blendshape weights and MPEG-4 FAPs; ``mimetic.animate.keyframes`` keys poses over time
(curves in ``.curves``, files in ``.clipfiles``). All talk
only to the rig's channels (the activation pivot).
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
