"""The names of the columns a robot observes, as plain data: the API's schemas, the policies'
layouts and the environments read them without loading the engine's compiled code."""

from __future__ import annotations

OBSERVATION_LABELS = (
    "reading",
    "reading_change",
    "gradient_x",
    "gradient_y",
    "gradient_z",
    "obstacle",
    "cell",
    "signal",
    "signal_change",
)
# The gradient's columns where robots steer continuously: read each step in the body frame.
BODY_GRADIENT_LABELS = ("gradient_forward", "gradient_side", "gradient_up")
