"""A tanh-Gaussian policy distribution whose draws ``torch.vmap`` gives each vmapped element its own.

TorchRL's ``TanhNormal`` draws its reparameterised sample through ``torch.distributions.Normal.rsample``,
which fills an empty tensor in place (``normal_``): ``torch.vmap(randomness="different")`` refuses an
in-place draw into an unbatched tensor, so the actor of a seed group (its seeds' parameters stacked, one
vmapped call) could not explore. :class:`TanhNormal` draws the same numbers with ``torch.randn``, a factory
that vmap batches:

    a = t(loc + scale * eps),   eps ~ N(0, 1),   t the tanh transform to [low, high]

Outside vmap its draws are TorchRL's number for number (``randn`` fills an empty tensor with ``normal_``
from the same generator: ``tests/test_seed_groups.py``).
"""
from __future__ import annotations

import torch
from torchrl.modules import TanhNormal as TorchRLTanhNormal

__all__ = ["TanhNormal"]


class TanhNormal(TorchRLTanhNormal):
    """TorchRL's ``TanhNormal`` with its reparameterised draws taken from ``torch.randn`` (see the module)."""

    def _preimage(self, sample_shape) -> torch.Tensor:
        normal = self.root_dist
        shape = torch.Size(sample_shape) + normal.loc.shape
        return normal.loc + torch.randn(shape, dtype=normal.loc.dtype, device=normal.loc.device) * normal.scale

    def rsample(self, sample_shape=torch.Size()) -> torch.Tensor:
        sample = self._preimage(sample_shape)
        for transform in self.transforms:
            sample = transform(sample)
        return sample

    def rsample_and_log_prob(self, sample_shape=()) -> tuple[torch.Tensor, torch.Tensor]:
        """The draw and its log-density, scored on the same pre-tanh value (as TorchRL's)."""
        preimage = self._preimage(sample_shape)
        transform = self.transforms[0]
        sample = transform(preimage)
        jacobian = transform.log_abs_det_jacobian(preimage, sample)
        if self.event_shape:
            jacobian = jacobian.sum(tuple(range(-len(self.event_shape), 0)))
        return sample, self.base_dist.log_prob(preimage) - jacobian
