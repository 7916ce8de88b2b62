"""Loss modules drltg adds to TorchRL's (SAC and TD3 come from ``torchrl.objectives``).

    SoftOptionCriticLoss   SAC over K options: intra-option policies, option-indexed critics,
                           terminations, a policy over options; K = 1 is exactly SAC      (soc)
    behaviour_cloning      w * mean ||mu(s) - a_demo||^2 on a batch's demonstrations   (behaviour_cloning)
                           (with options: sum_o pi_Omega(o|s) ||mu_o(s) - a_demo||^2)
    option_labels          the option a demonstration is credited to: o ~ pi_Omega(.|s)
    distillation           kickstarting: w_f * mean D(pi_T(.|s), pi_S(.|s)) towards a teacher  (distillation)
    KickstartingWeight     w_f, falling linearly or exponentially to 0 over a number of frames
    SuccessorFeatureLoss   psi(s, a) <- phi + gamma (1 - terminated) psi_target(s', pi(s'))  (successor_features)
"""
from drltg.losses.behaviour_cloning import behaviour_cloning, option_labels
from drltg.losses.distillation import KickstartingWeight, distillation
from drltg.losses.soc import SoftOptionCriticLoss
from drltg.losses.successor_features import SuccessorFeatureLoss

__all__ = ["SoftOptionCriticLoss", "SuccessorFeatureLoss", "behaviour_cloning", "option_labels", "distillation",
           "KickstartingWeight"]
