"""depthgram.act: from the scene tree to actions (grasp, avoid) and the clearance channel."""

from depthgram.act.channel import Channel, clearance_channel, column_clearance, openings
from depthgram.act.config import CHANNEL_CHOICES, ActConfig
from depthgram.act.plan import ACTIONS, Action, Plan, TtcWarning, plan, plan_to_dict, plan_to_text

__all__ = [
    "ACTIONS",
    "CHANNEL_CHOICES",
    "ActConfig",
    "Action",
    "Channel",
    "Plan",
    "TtcWarning",
    "clearance_channel",
    "column_clearance",
    "openings",
    "plan",
    "plan_to_dict",
    "plan_to_text",
]
