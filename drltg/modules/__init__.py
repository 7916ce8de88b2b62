"""Networks and policies that drltg's learners need beyond TorchRL's own modules."""
from drltg.modules.options import (
    OPTION_KEY,
    OptionHeads,
    OptionSelector,
    make_option_actor,
    make_option_policy,
    make_option_qvalue,
    make_termination,
    option_statistics,
    option_transforms,
)

__all__ = [
    "OPTION_KEY",
    "OptionHeads",
    "OptionSelector",
    "make_option_actor",
    "make_option_policy",
    "make_option_qvalue",
    "make_termination",
    "option_statistics",
    "option_transforms",
]
