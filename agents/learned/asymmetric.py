"""Asymmetric actor-critic PPO (issue 21): the critic sees the observation and the episode's privileged
vector (:mod:`gfb_agents.learned.privileged`), the actor only the observation (with its frame stack).

The SB3 way: the training env's observation is a ``Dict`` ``{"obs", "privileged"}``
(:class:`~gfb_agents.learned.vec_env.PrivilegedVecEnv`, then ``VecNormalize`` and ``VecFrameStack`` as for
plain PPO); :class:`AsymmetricActorCriticPolicy` is an ``ActorCriticPolicy`` with separate features
extractors (``share_features_extractor=False``): the actor's (:class:`ObservationExtractor`) flattens
``"obs"`` only, the critic's (:class:`CriticExtractor`) ``"obs"`` and ``"privileged"``; the MLP extractor
gets one input size per branch (:class:`AsymmetricMlpExtractor`).  The privileged vector is an input of
the value only: it shapes the advantages the actor learns from, never the actor's input.

Deployment uses the actor alone: :class:`DeployedActor` (the actor's features, MLP and action head, and
the action's log std) acts from the public observation (normalised and stacked by
:class:`~gfb_agents.learned.evaluate.LearnedPolicy` as in training).  :meth:`DeployedActor.save` writes
``actor.pt`` -- weights of the actor only, no critic, no optimiser state: the committed copy.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor, MlpExtractor
from torch import nn

from gfb_agents.learned.privileged import OBS_KEY, PRIVILEGED_KEY

__all__ = [
    "ObservationExtractor",
    "CriticExtractor",
    "AsymmetricMlpExtractor",
    "AsymmetricActorCriticPolicy",
    "DeployedActor",
    "ACTOR_FILE",
]

#: the deployed actor's file (beside ``vecnormalize.pkl`` and ``policy.json``)
ACTOR_FILE = "actor.pt"
_ACTIVATIONS = {"Tanh": nn.Tanh, "ReLU": nn.ReLU, "ELU": nn.ELU, "LeakyReLU": nn.LeakyReLU}


def _flat_dim(space: spaces.Space) -> int:
    return int(np.prod(space.shape))


class ObservationExtractor(BaseFeaturesExtractor):
    """The actor's features: the (stacked, normalised) observation ``"obs"`` flattened; nothing else."""

    def __init__(self, observation_space: spaces.Dict):
        super().__init__(observation_space, features_dim=_flat_dim(observation_space[OBS_KEY]))

    def forward(self, observations: dict[str, th.Tensor]) -> th.Tensor:
        return th.flatten(observations[OBS_KEY], start_dim=1)


class CriticExtractor(BaseFeaturesExtractor):
    """The critic's features: ``"obs"`` and ``"privileged"`` flattened, side by side."""

    def __init__(self, observation_space: spaces.Dict):
        dim = _flat_dim(observation_space[OBS_KEY]) + _flat_dim(observation_space[PRIVILEGED_KEY])
        super().__init__(observation_space, features_dim=dim)

    def forward(self, observations: dict[str, th.Tensor]) -> th.Tensor:
        return th.cat(
            [
                th.flatten(observations[OBS_KEY], start_dim=1),
                th.flatten(observations[PRIVILEGED_KEY], start_dim=1),
            ],
            dim=1,
        )


class AsymmetricMlpExtractor(MlpExtractor):
    """SB3's ``MlpExtractor`` with its own input size for the value branch (SB3's has one for both)."""

    def __init__(
        self,
        pi_dim: int,
        vf_dim: int,
        net_arch: list[int] | dict[str, list[int]],
        activation_fn: type[nn.Module],
        device: th.device | str = "auto",
    ):
        super().__init__(pi_dim, net_arch, activation_fn, device)
        critic = MlpExtractor(vf_dim, net_arch, activation_fn, device)
        self.value_net, self.latent_dim_vf = critic.value_net, critic.latent_dim_vf


class AsymmetricActorCriticPolicy(ActorCriticPolicy):
    """``ActorCriticPolicy`` over the ``{"obs", "privileged"}`` observation: the actor reads ``"obs"`` only
    (:class:`ObservationExtractor`), the critic both (:class:`CriticExtractor`).  The features extractors
    are fixed (``features_extractor_class`` / ``share_features_extractor`` may not be set)."""

    def __init__(
        self, observation_space: spaces.Dict, action_space: spaces.Space, lr_schedule, **kwargs: Any
    ):
        if not isinstance(observation_space, spaces.Dict) or set(observation_space.spaces) != {
            OBS_KEY,
            PRIVILEGED_KEY,
        }:
            raise ValueError(
                f"AsymmetricActorCriticPolicy needs a Dict observation {{{OBS_KEY!r}, {PRIVILEGED_KEY!r}}}, "
                f"got {observation_space}"
            )
        for k in ("features_extractor_class", "share_features_extractor", "features_extractor_kwargs"):
            if kwargs.get(k) not in (None, ObservationExtractor, False, {}):
                raise ValueError(f"policy_kwargs {k}: fixed by the asymmetric policy")
            kwargs.pop(k, None)
        super().__init__(
            observation_space,
            action_space,
            lr_schedule,
            features_extractor_class=ObservationExtractor,
            share_features_extractor=False,
            **kwargs,
        )

    def _build(self, lr_schedule) -> None:
        # ActorCriticPolicy made both extractors of features_extractor_class; the critic's reads both keys
        self.vf_features_extractor = CriticExtractor(self.observation_space)
        super()._build(lr_schedule)

    def _build_mlp_extractor(self) -> None:
        self.mlp_extractor = AsymmetricMlpExtractor(
            self.pi_features_extractor.features_dim,
            self.vf_features_extractor.features_dim,
            net_arch=self.net_arch,
            activation_fn=self.activation_fn,
            device=self.device,
        )

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        # fixed here: not passed back to __init__ on load
        data.pop("features_extractor_class", None)
        data.pop("features_extractor_kwargs", None)
        return data


class DeployedActor(nn.Module):
    """The actor of a trained policy, alone: observation features -> MLP -> action mean (+ log std).

    ``predict`` has SB3's signature and semantics for a Box action (deterministic: the mean; else a
    Gaussian sample; clipped to the action space), on the already normalised (and stacked) observation.
    It has no input for the privileged vector."""

    def __init__(
        self,
        obs_dim: int,
        hidden: list[int],
        activation: str,
        action_low: np.ndarray,
        action_high: np.ndarray,
    ):
        super().__init__()
        if activation not in _ACTIVATIONS:
            raise ValueError(f"activation must be one of {sorted(_ACTIVATIONS)}, got {activation!r}")
        layers: list[nn.Module] = []
        last = int(obs_dim)
        for h in hidden:
            layers += [nn.Linear(last, int(h)), _ACTIVATIONS[activation]()]
            last = int(h)
        self.obs_dim, self.hidden, self.activation = int(obs_dim), [int(h) for h in hidden], activation
        self.policy_net = nn.Sequential(*layers)
        self.action_low = np.asarray(action_low, dtype=np.float32)
        self.action_high = np.asarray(action_high, dtype=np.float32)
        self.action_net = nn.Linear(last, self.action_low.size)
        self.log_std = nn.Parameter(th.zeros(self.action_low.size))

    @classmethod
    def from_policy(cls, policy: ActorCriticPolicy) -> DeployedActor:
        """The actor of an SB3 ``ActorCriticPolicy`` (its ``mlp_extractor.policy_net`` and ``action_net``
        on flattened observation features: the asymmetric policy, or a student's), weights copied."""
        acts = {type(m).__name__ for m in policy.mlp_extractor.policy_net if not isinstance(m, nn.Linear)}
        hidden = [m.out_features for m in policy.mlp_extractor.policy_net if isinstance(m, nn.Linear)]
        space = policy.observation_space
        obs_space = space[OBS_KEY] if isinstance(space, spaces.Dict) else space
        act = acts.pop() if acts else "Tanh"
        self = cls(_flat_dim(obs_space), hidden, act, policy.action_space.low, policy.action_space.high)
        self.policy_net.load_state_dict(policy.mlp_extractor.policy_net.state_dict())
        self.action_net.load_state_dict(policy.action_net.state_dict())
        with th.no_grad():
            self.log_std.copy_(policy.log_std.detach())
        return self

    def forward(self, obs: th.Tensor) -> th.Tensor:
        """The action mean of a batch of (normalised, stacked) observations."""
        return self.action_net(self.policy_net(obs))

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        x = np.asarray(observation, dtype=np.float32)
        single = x.ndim == 1
        if x.shape[-1] != self.obs_dim:
            raise ValueError(f"observation has {x.shape[-1]} entries, the actor takes {self.obs_dim}")
        with th.no_grad():
            mean = self.forward(th.as_tensor(x.reshape(-1, self.obs_dim)))
            a = mean if deterministic else mean + th.exp(self.log_std) * th.randn_like(mean)
        out = np.clip(a.numpy(), self.action_low, self.action_high)
        return (out[0] if single else out), state

    def save(self, path: str | Path, meta: dict[str, Any] | None = None) -> Path:
        """``actor.pt``: the architecture and the actor's weights (tensors and plain values only, loadable
        with ``torch.load(weights_only=True)``); ``meta``: plain values kept beside them."""
        blob = {
            "obs_dim": self.obs_dim,
            "hidden": self.hidden,
            "activation": self.activation,
            "action_low": self.action_low.tolist(),
            "action_high": self.action_high.tolist(),
            "state_dict": {k: v.detach().clone() for k, v in self.state_dict().items()},
            "meta": dict(meta or {}),
        }
        th.save(blob, str(path))
        return Path(path)

    @classmethod
    def load(cls, path: str | Path) -> DeployedActor:
        blob = th.load(str(path), map_location="cpu", weights_only=True)
        self = cls(
            blob["obs_dim"], blob["hidden"], blob["activation"], blob["action_low"], blob["action_high"]
        )
        self.load_state_dict(blob["state_dict"])
        self.meta = blob.get("meta", {})
        return self.eval()
