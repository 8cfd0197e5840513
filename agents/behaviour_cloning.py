"""Behaviour cloning: an MLP fitted by least squares to a dataset's (observation, action) pairs.

The simplest offline learner (Pomerleau, 1991; the "BC" baseline of D4RL, Fu et al., 2020): a policy
``a = tanh(MLP((o - mean) / std))`` trained to minimise the mean squared error to the behaviour policy's actions
on the dataset's decision steps, with Adam (Kingma and Ba, 2015).  The observation statistics are the dataset's;
the output is squashed by tanh because every action of the suite's contouring envs lies in [-1, 1] (the axis
commands as a fraction of ``u_max``).  A behaviour policy with internal state (an integrator, a feedforward that
reads the reference ahead) is cloned from the observation alone: what BC can and cannot copy is part of the
figure.

The trained policy is saved as a **data-only** ``.npz`` (weights, biases, the observation statistics, and a JSON
header with the env signature, :func:`vcnc_agents.policy.env_signature`, and the training's settings and losses) and
loaded without unpickling (``allow_pickle=False``); it runs with numpy, without torch, as a policy with SB3's
``predict`` (``vcnc-bench --policy bc:PATH``).

Example
-------
>>> import minari, gymnasium as gym, vcnc_gym
>>> from vcnc_agents.behaviour_cloning import dataset_pairs, fit, load_bc
>>> obs, act = dataset_pairs(minari.load_dataset("vcnc/Heart-v1/strongest-v0"))   # doctest: +SKIP
>>> bc = fit(obs, act, epochs=20)                                                     # doctest: +SKIP
>>> bc.save("heart-bc.npz")                                                            # doctest: +SKIP
>>> policy = load_bc("heart-bc.npz", gym.make("VCNC-Heart-v1"))                        # doctest: +SKIP
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vcnc_gym.validation import integer, positive

from .policy import check_env_signature, env_signature

__all__ = ["BehaviourCloning", "dataset_pairs", "stack_history", "fit", "load_bc", "FORMAT", "main"]

#: The file format's name and version, in the header.
FORMAT = "vcnc-gym behaviour cloning v1"

#: The per-epoch train and validation MSEs are evaluated on at most this many pairs of each set.
EVAL_PAIRS = 50_000

#: Standard deviations below this are taken as 1 (an observation entry constant over the dataset).
_MIN_STD = 1e-8


@dataclass
class BehaviourCloning:
    """A fitted behaviour-cloning policy: an MLP with tanh hidden layers and a tanh output, in float32 numpy.

    Attributes
    ----------
    weights, biases : list of ndarray
        Layer ``k`` maps ``x`` to ``x @ weights[k] + biases[k]``; tanh after every layer, the last included.
    obs_mean, obs_std : ndarray, (D,)
        The dataset's observation statistics (inputs are ``(o - mean) / std``).
    header : dict
        ``format``, ``signature`` (the env's :func:`vcnc_agents.policy.env_signature`, or None), the training's
        ``settings`` and ``losses`` (train and validation MSE per epoch), ``source`` (the dataset id, optional).
    """

    weights: list
    biases: list
    obs_mean: np.ndarray
    obs_std: np.ndarray
    header: dict = field(default_factory=dict)

    #: Not a learning-across-episodes policy, and causal: it reads the observation only.
    causal = True

    @property
    def history(self) -> int:
        """Observations per input: the current one and the ``history - 1`` before it (``header["history"]``)."""
        return int(self.header.get("history", 1))

    def forward(self, obs: np.ndarray) -> np.ndarray:
        """The actions of a batch of inputs, (M, history x D) -> (M, A), float32 (newest observation first)."""
        x = (np.asarray(obs, dtype=np.float32) - self.obs_mean) / self.obs_std
        for w, b in zip(self.weights, self.biases):
            x = np.tanh(x @ w + b)
        return x

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        """SB3's ``predict``: the action for one observation (D,) or a batch (M, D); ``state`` is passed back.

        With ``history`` > 1 the policy keeps each env's last observations; an env whose ``episode_start`` is
        True (or the first call, or a batch of another size) starts its history with the current observation
        repeated, as :func:`dataset_pairs` pads an episode's start."""
        obs = np.asarray(observation, dtype=np.float32)
        single = obs.ndim == 1
        obs = obs[None] if single else obs
        k = self.history
        if k > 1:
            buf = getattr(self, "_history", None)
            if buf is None or buf.shape[0] != obs.shape[0]:
                buf = self._history = np.repeat(obs[:, None], k, axis=1)
            else:
                start = (
                    np.ones(obs.shape[0], dtype=bool)
                    if episode_start is None
                    else np.asarray(episode_start, dtype=bool).reshape(-1)
                )
                buf[:, 1:] = buf[:, :-1].copy()
                buf[:, 0] = obs
                buf[start] = obs[start][:, None]
            obs = buf.reshape(obs.shape[0], -1)
        action = self.forward(obs)
        return (action[0] if single else action), state

    def check_env(self, env) -> None:
        """ValueError naming every field where ``env`` differs from the env the dataset came from."""
        recorded = self.header.get("signature")
        if recorded:
            check_env_signature(recorded, env, what="the behaviour-cloning policy")
        d = int(np.prod(env.observation_space.shape))
        if d * self.history != self.obs_mean.size:
            raise ValueError(
                f"env has {d} observation entries, the behaviour-cloning policy {self.obs_mean.size // self.history}"
            )

    def save(self, path) -> Path:
        """Write the data-only ``.npz`` (numbers and a JSON header, nothing pickled); returns its path."""
        path = Path(path)
        arrays = {
            "obs_mean": self.obs_mean,
            "obs_std": self.obs_std,
            "header": np.array(json.dumps(self.header, sort_keys=True)),
        }
        for k, (w, b) in enumerate(zip(self.weights, self.biases)):
            arrays[f"w{k}"], arrays[f"b{k}"] = w, b
        with open(path, "wb") as f:
            np.savez(f, **arrays)
        return path

    @classmethod
    def load(cls, path) -> "BehaviourCloning":
        """Read a file :meth:`save` wrote (``allow_pickle=False``); ValueError naming ``path`` if it is not one."""
        path = Path(path)
        if not path.is_file():
            raise ValueError(f"path {str(path)!r} is not a file (a behaviour-cloning .npz)")
        try:
            with np.load(path, allow_pickle=False) as z:
                header = json.loads(str(z["header"]))
                n = sum(1 for k in z.files if k.startswith("w"))
                weights = [z[f"w{k}"].astype(np.float32) for k in range(n)]
                biases = [z[f"b{k}"].astype(np.float32) for k in range(n)]
                mean, std = z["obs_mean"].astype(np.float32), z["obs_std"].astype(np.float32)
        except (OSError, KeyError, ValueError) as exc:
            raise ValueError(f"path {str(path)!r} is not a behaviour-cloning file: {exc}") from exc
        if header.get("format") != FORMAT:
            raise ValueError(f"path {str(path)!r} has format {header.get('format')!r}, expected {FORMAT!r}")
        return cls(weights, biases, mean, std, header)


def load_bc(path, env=None) -> BehaviourCloning:
    """The policy in ``path`` (:meth:`BehaviourCloning.load`), checked against ``env`` when given."""
    policy = BehaviourCloning.load(path)
    if env is not None:
        policy.check_env(env)
    return policy


def stack_history(observations: np.ndarray, history: int) -> np.ndarray:
    """One episode's inputs with ``history`` observations each: row t is ``o_t, o_(t-1), ..., o_(t-history+1)``
    (newest first), an episode's start padded with its first observation; (T, D) -> (T, history x D)."""
    o = np.asarray(observations, dtype=np.float32)
    history = integer("history", history, 1)
    idx = np.maximum(np.arange(o.shape[0])[:, None] - np.arange(history)[None], 0)
    return o[idx].reshape(o.shape[0], -1)


def dataset_pairs(dataset, history: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Every decision step's (input, action) of a Minari dataset: ((S, history x D) float32, (S, A) float32),
    the input the observation the action answered and the ``history - 1`` before it (:func:`stack_history`;
    each episode's last observation has no action and is left out)."""
    obs, act = [], []
    for ep in dataset.iterate_episodes():
        obs.append(stack_history(ep.observations[:-1], history))
        act.append(np.asarray(ep.actions, dtype=np.float32))
    if not obs:
        raise ValueError("dataset has no episodes")
    return np.concatenate(obs), np.concatenate(act)


def fit(
    observations,
    actions,
    *,
    hidden=(256, 256),
    epochs: int = 20,
    batch_size: int = 1024,
    learning_rate: float = 1e-3,
    validation: float = 0.05,
    seed: int = 0,
    signature: dict | None = None,
    source: str | None = None,
    history: int = 1,
    progress=None,
) -> BehaviourCloning:
    """Fit an MLP to ``(observations, actions)`` by mean squared error (torch, Adam, on the CPU).

    Parameters
    ----------
    observations : array, (S, history x D)
        The inputs (:func:`dataset_pairs` with the same ``history``).
    actions : array, (S, A), in [-1, 1]
        Values outside are clipped (the env clips them too).
    hidden : sequence of int
        Widths of the hidden layers (tanh).
    epochs, batch_size : int
        Passes over the training pairs and pairs per Adam step.
    learning_rate : float
        Adam's step size.
    validation : float
        Fraction of the pairs held out (a random choice) for the validation MSE, in [0, 0.5).
    seed : int
        Seeds the split, the initial weights and the batches.
    signature : dict, optional
        The env's :func:`vcnc_agents.policy.env_signature`, checked when the policy is loaded for an env.
    source : str, optional
        Where the pairs came from (a dataset id), kept in the header.
    history : int
        Observations per input (the policy keeps that many per env when it runs).
    progress : callable (epoch, train_mse, validation_mse), optional

    Returns
    -------
    BehaviourCloning
        With ``header["losses"]``: ``{"train": [...], "validation": [...], "initial_train": float}`` (MSE of the
        actions, per epoch, on at most :data:`EVAL_PAIRS` pairs of each set, a fixed random choice).
    """
    import torch

    obs = np.asarray(observations, dtype=np.float32)
    act = np.clip(np.asarray(actions, dtype=np.float32), -1.0, 1.0)
    if obs.ndim != 2 or act.ndim != 2 or obs.shape[0] != act.shape[0] or obs.shape[0] < 2:
        raise ValueError(
            f"observations (S, D) and actions (S, A) must have the same S >= 2, got {obs.shape} and {act.shape}"
        )
    if not (np.isfinite(obs).all() and np.isfinite(act).all()):
        raise ValueError("observations and actions must be finite")
    history = integer("history", history, 1)
    if obs.shape[1] % history:
        raise ValueError(f"history={history} does not divide the input's {obs.shape[1]} entries")
    hidden = [integer("hidden", h, 1) for h in hidden]
    epochs = integer("epochs", epochs, 1)
    batch_size = integer("batch_size", batch_size, 1)
    learning_rate = positive("learning_rate", learning_rate)
    if not 0 <= validation < 0.5:
        raise ValueError(f"validation must be in [0, 0.5), got {validation!r}")
    rng = np.random.default_rng(integer("seed", seed, 0))
    torch.manual_seed(seed)
    order = rng.permutation(obs.shape[0])
    n_val = int(round(validation * obs.shape[0]))
    val, train = order[:n_val], order[n_val:]
    mean = obs[train].mean(axis=0)
    std = obs[train].std(axis=0)
    std = np.where(std > _MIN_STD, std, 1.0).astype(np.float32)
    x = torch.from_numpy((obs - mean) / std)
    y = torch.from_numpy(act)
    sizes = [obs.shape[1], *hidden, act.shape[1]]
    layers = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        layers += [torch.nn.Linear(a, b), torch.nn.Tanh()]
    net = torch.nn.Sequential(*layers)
    opt = torch.optim.Adam(net.parameters(), lr=learning_rate)
    train_t, val_t = torch.from_numpy(train), torch.from_numpy(val)

    # the per-epoch MSEs on at most EVAL_PAIRS pairs of each set (a fixed random choice): a figure, not the loss
    train_eval, val_eval = train_t[:EVAL_PAIRS], val_t[:EVAL_PAIRS]

    def mse(idx) -> float:
        if idx.numel() == 0:
            return math.nan
        with torch.no_grad():
            return float(torch.mean((net(x[idx]) - y[idx]) ** 2))

    losses = {"initial_train": mse(train_eval), "train": [], "validation": []}
    t0 = time.perf_counter()
    for epoch in range(epochs):
        perm = train_t[torch.from_numpy(rng.permutation(train.size))]
        for k in range(0, perm.numel(), batch_size):
            idx = perm[k : k + batch_size]
            loss = torch.mean((net(x[idx]) - y[idx]) ** 2)
            opt.zero_grad()
            loss.backward()
            opt.step()
        losses["train"].append(mse(train_eval))
        losses["validation"].append(mse(val_eval))
        if progress is not None:
            progress(epoch + 1, losses["train"][-1], losses["validation"][-1])
    linears = [m for m in net if isinstance(m, torch.nn.Linear)]
    header = {
        "format": FORMAT,
        "signature": signature,
        "source": source,
        "losses": losses,
        "history": history,
        "settings": {
            "hidden": hidden,
            "epochs": epochs,
            "batch_size": batch_size,
            "learning_rate": learning_rate,
            "validation": validation,
            "seed": seed,
            "pairs": int(obs.shape[0]),
            "train_s": time.perf_counter() - t0,
        },
    }
    return BehaviourCloning(
        weights=[m.weight.detach().numpy().T.astype(np.float32).copy() for m in linears],
        biases=[m.bias.detach().numpy().astype(np.float32).copy() for m in linears],
        obs_mean=mean.astype(np.float32),
        obs_std=std,
        header=header,
    )


def main(argv: list[str] | None = None) -> int:
    """``python -m vcnc_agents.behaviour_cloning DATASET_ID --out FILE``: fit to a local Minari dataset and save."""
    import argparse
    import sys

    p = argparse.ArgumentParser(prog="python -m vcnc_agents.behaviour_cloning", description=main.__doc__)
    p.add_argument("dataset", nargs="+", help="local Minari dataset id(s) (vcnc-datasets); pairs pooled")
    p.add_argument("--out", required=True, help="the .npz to write")
    p.add_argument("--epochs", type=int, default=20)
    p.add_argument("--hidden", type=int, nargs="+", default=[256, 256])
    p.add_argument("--batch-size", type=int, default=1024)
    p.add_argument("--learning-rate", type=float, default=1e-3)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--history", type=int, default=1, help="observations per input (default 1: the current one)")
    args = p.parse_args(argv)
    from vcnc_gym.extras import require_extra

    require_extra("datasets", "vcnc_agents.behaviour_cloning's command")
    import minari

    import vcnc_gym  # noqa: F401  (registers the ids recover_environment makes)

    pairs, spec_ids = [], set()
    for name in args.dataset:
        ds = minari.load_dataset(name)
        pairs.append(dataset_pairs(ds, args.history))
        env = ds.recover_environment()
        signature = env_signature(env)
        spec_ids.add(env.spec.id)
        env.close()
    if len(spec_ids) != 1:
        print(f"datasets are of several envs {sorted(spec_ids)}: give one env's", file=sys.stderr)
        return 2
    obs = np.concatenate([o for o, _ in pairs])
    act = np.concatenate([a for _, a in pairs])
    print(f"{obs.shape[0]} pairs from {', '.join(args.dataset)}", flush=True)

    def report(epoch, tr, va):
        print(f"epoch {epoch:3d}: train MSE {tr:.4g}, validation MSE {va:.4g}", flush=True)

    bc = fit(
        obs,
        act,
        hidden=args.hidden,
        epochs=args.epochs,
        batch_size=args.batch_size,
        learning_rate=args.learning_rate,
        seed=args.seed,
        signature=signature,
        source=" + ".join(args.dataset),
        history=args.history,
        progress=report,
    )
    print(
        f"wrote {bc.save(args.out)} (initial train MSE {bc.header['losses']['initial_train']:.4g}, "
        f"{bc.header['settings']['train_s']:.1f} s)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
