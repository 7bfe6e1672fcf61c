"""The adversary restricted to Markov policies: a variant of the game of thesis §5.3.

In the thesis (§6.1; its strategies mixed as in Def. 5.3.1) the adversary plays one deterministic history-dependent policy in
every dynamics at once: the loss is scored under tau, the feature sums under tau_1..tau_D, and its
best response is a policy that is best over several MDPs (chapter 6):

    max_pi  sum_{j=0..D} E_j[ sum_{t=0..T-1} R_j(t, s_t) | P_j, pi, s_0 ~ p0 ],
    R_0(t, s) = (learner's expected loss against s at t),  R_j(t, s) = w_j . phi(s)  (j >= 1).

A history tells the dynamics apart when they differ enough, so such a policy can maximise the
loss in tau and match the demonstrations in tau_j separately; the feature constraints then cost it
nothing and the minimiser of eq. 5.9 is the zero reward (measured in experiments/README.md). This
variant restricts the adversary to deterministic **Markov** policies pi_t(s), which act the same in
every dynamics: the same objective over a smaller strategy set, so f(w) can only fall and the
certified learner, the bounds and the degeneracy check apply unchanged. Nothing else of the game
changes (the learner still mixes Markov policies under tau).

Its best response is the Markov multi-model MDP problem (NP-hard in general). The oracle here
solves it by CADP (coordinate ascent with dynamic programming, Su & Petrik 2023, from WSU;
``airl_cli.core.mmdp.baselines``), a local optimum: the certificate then holds against CADP's
best responses, as PBVI's does against PBVI's. ``exact=True`` enumerates every Markov policy
(A^(S (T-1)) of them: tiny problems, tests).
"""

from __future__ import annotations

import itertools

import numpy as np

from airl_cli.core.irl.game_problem import AdversaryOracle
from airl_cli.core.mdp.planning import state_marginals
from airl_cli.core.mdp.sparse import SparseDynamics
from airl_cli.core.mmdp.baselines import cadp, markov_returns
from airl_cli.core.mmdp.policy_graph import layered_rewards

#: Largest number of Markov policies ``exact=True`` enumerates.
MAX_ENUMERATED = 1 << 16


def markov_oracle(transitions: np.ndarray | SparseDynamics, initial: np.ndarray, *, exact: bool = False) -> AdversaryOracle:
    """The Markov adversary's best response, as a function of its rewards.

    Args:
        transitions: (M, S, A, S) dynamics, tau at index 0 (a ``SparseDynamics`` is made dense).
        initial: (S,) p0.
        exact: enumerate every deterministic Markov policy instead of CADP (tiny problems).

    Returns:
        ``oracle(R)`` for rewards R (M, T, S): (sum_j of the returned policy's exact returns, its
        state marginals (M, T, S) under each dynamics), as ``airl_cli.core.irl.game.AdversaryOracle``.

    Raises:
        ValueError: ``exact`` with more than ``MAX_ENUMERATED`` policies.
    """
    P = transitions.dense() if isinstance(transitions, SparseDynamics) else np.asarray(transitions, dtype=np.float64)
    p0 = np.asarray(initial, dtype=np.float64)
    M, S, A, _ = P.shape

    def oracle(R: np.ndarray) -> tuple[float, np.ndarray]:
        L = layered_rewards(P, R)
        policy = _best_enumerated(P, L, p0) if exact else cadp(P, L, p0)[0]
        value = float(markov_returns(P, L, policy, p0).sum())
        return value, np.stack([state_marginals(P[j], policy, p0) for j in range(M)])

    return oracle


def _best_enumerated(P: np.ndarray, L, p0: np.ndarray) -> np.ndarray:
    """(T-1, S) the Markov policy of largest summed return over every deterministic Markov policy
    (ties: the first in lexicographic order of the flattened actions)."""
    M, S, A, _ = P.shape
    steps = L.step.shape[1]
    n = A ** (steps * S)
    if n > MAX_ENUMERATED:
        raise ValueError(f"exact enumeration of the Markov adversary's {n} policies is too large (at most {MAX_ENUMERATED})")
    best, best_value = None, -np.inf
    for actions in itertools.product(range(A), repeat=steps * S):
        policy = np.array(actions, dtype=np.int64).reshape(steps, S)
        value = float(markov_returns(P, L, policy, p0).sum())
        if value > best_value + 1e-12:
            best, best_value = policy, value
    return best
