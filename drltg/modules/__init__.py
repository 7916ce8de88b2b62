"""Networks and policies that drltg's learners need beyond TorchRL's own modules, and loading weights
across networks of different shapes (model reuse), and the parts of successor features: reward features
phi with their weights w (exact or regressed) and successor-feature critics psi; and min_k Q_k of a loss's
critic ensemble, which behaviour cloning, value shaping and GPI read."""
from drltg.modules.critics import min_over_critics
from drltg.modules.distributions import TanhNormal
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
from drltg.modules.reward_features import GoalFeatures, regress_weights
from drltg.modules.successor_features import SF_KEY, make_sf_critic
from drltg.modules.weights import LoadReport, freeze_parameters, load_weights

__all__ = [
    "min_over_critics",
    "TanhNormal",
    "LoadReport",
    "freeze_parameters",
    "load_weights",
    "OPTION_KEY",
    "OptionHeads",
    "OptionSelector",
    "make_option_actor",
    "make_option_policy",
    "make_option_qvalue",
    "make_termination",
    "option_statistics",
    "option_transforms",
    "GoalFeatures",
    "regress_weights",
    "SF_KEY",
    "make_sf_critic",
]
