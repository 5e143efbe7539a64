"""The attention node's algorithm: whom to look at, and the pan/tilt control law (Ban et al.)."""

from services.attention.core.attention import Chooser, Decision, Person
from services.attention.core.servo import HeadGeometry, ServoParams, ServoResult, head_angles, rest_rates, servo

__all__ = ["Chooser", "Decision", "HeadGeometry", "Person", "ServoParams", "ServoResult", "head_angles", "rest_rates",
           "servo"]
