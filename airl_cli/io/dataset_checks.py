"""The checks of a dataset file's keys (``airl_cli.io.dataset``), one function per key or group of keys.

Each raises ``DatasetError`` with one sentence naming the key, and returns the checked array
(float64 or int64), so that ``data.validate`` builds its ``Dataset`` from their results.
"""

from __future__ import annotations

import numpy as np

from airl_cli.core.mdp.basics import check_probabilities
from airl_cli.core.mdp.sparse import SparseDynamics
from airl_cli.core.numerics.magnitude import MAX_SUM, largest_sum
from airl_cli.errors import DatasetError

#: The two keys of the sparse form of the dynamics.
SPARSE_KEYS = ("transition_next", "transition_probs")
TEST_KEYS = ("test_transitions", "test_transition_next", "test_transition_probs")


def fail(message: str) -> None:
    raise DatasetError(message)


def numeric(key: str, x: np.ndarray, *, integer: bool = False) -> np.ndarray:
    if x.dtype == object or not (np.issubdtype(x.dtype, np.number) or x.dtype == np.bool_):
        fail(f"key '{key}' must hold numbers, but holds {x.dtype} values")
    if np.issubdtype(x.dtype, np.complexfloating):
        fail(f"key '{key}' must hold real numbers, not complex ones")
    if integer:
        if not np.issubdtype(x.dtype, np.integer):
            fail(f"key '{key}' must hold integers (state or action indices), but holds {x.dtype} values")
        return x.astype(np.int64)
    x = x.astype(np.float64)
    if not np.all(np.isfinite(x)):
        idx = tuple(int(i) for i in np.argwhere(~np.isfinite(x))[0])
        fail(f"key '{key}' has a NaN or infinite value at index {idx}")
    return x


def shape(key: str, x: np.ndarray, expected: tuple, meaning: str) -> None:
    if x.shape != expected:
        fail(f"key '{key}' must have shape {meaning} = {expected}, but has shape {x.shape}")


def renormalised(raw: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``x``, the float64 copy of a file's probabilities ``raw`` (rows along the last axis), each row
    divided by its sum where ``raw`` is a float of fewer than 64 bits (float32, float16) and every
    row sums to 1 within that type's rounding (4 eps a term): such rows cannot sum to 1 within the
    checks' 1e-8 as written. Any other ``x`` as it is (the checks then judge it)."""
    if not (np.issubdtype(raw.dtype, np.floating) and raw.dtype.itemsize < 8) or x.size == 0:
        return x
    sums = x.sum(axis=-1, keepdims=True)
    if np.all(np.abs(sums - 1.0) <= 4 * np.finfo(raw.dtype).eps * x.shape[-1]):
        return x / sums
    return x


def probabilities(key: str, x: np.ndarray) -> None:
    try:
        check_probabilities(x, name=f"key '{key}'")
    except ValueError as err:
        fail(str(err))


def dynamics(raw: dict[str, np.ndarray], prefix: str = "") -> np.ndarray | SparseDynamics:
    """The (M, S, A, S) dynamics from the dense key, or a ``SparseDynamics`` from the two sparse ones,
    checked. ``prefix="test_"``: the held-out test dynamics (E, S, A, S), keys 'test_transitions'
    or 'test_transition_next' with 'test_transition_probs' (M >= 1 instead of M >= 2)."""
    dense, nxt_key, probs_key = (prefix + k for k in ("transitions", *SPARSE_KEYS))
    sparse = [k for k in (nxt_key, probs_key) if k in raw]
    if dense in raw and sparse:
        fail(f"give the dynamics once: either '{dense}' or '{nxt_key}' with '{probs_key}', not both ('{sparse[0]}' is there too)")
    if dense not in raw and len(sparse) < 2:
        missing = f"the required key '{dense}' is missing" if not sparse else f"'{sparse[0]}' is given without '{({nxt_key, probs_key} - {sparse[0]}).pop()}'"
        fail(f"{missing}; give the dynamics as '{dense}' (M, S, A, S) or as '{nxt_key}' (S, R) with '{probs_key}' (M, S, A, R)")
    if dense in raw:
        P = renormalised(np.asarray(raw[dense]), numeric(dense, np.asarray(raw[dense])))
        if P.ndim != 4 or P.shape[1] != P.shape[3]:
            fail(f"key '{dense}' must have shape (M, S, A, S), but has shape {P.shape}")
        key = dense
    else:
        P = sparse_keys(raw, prefix)
        key = probs_key
    M, S, A, _ = P.shape
    if M < (1 if prefix else 2):
        what = "at least one test dynamics (E >= 1)" if prefix else "tau and at least one tau_j (M >= 2)"
        fail(f"key '{key}' must stack {what}, but has shape {np.shape(raw[key])}")
    if S < 1 or A < 1:
        fail(f"key '{key}' needs at least one state and one action, but has shape {np.shape(raw[key])}")
    probabilities(key, P.probs if isinstance(P, SparseDynamics) else P)
    return P


def features(raw: dict, S: int, A: int, T: int) -> np.ndarray:
    """The key 'features': phi (S, K), phi(s, a) (S, A, K), phi_t(s) (T, S, K) or phi_t(s, a) (T-1, S, A, K).

    A three-axis array that fits both (S, A, K) and (T, S, K) (T = S = A) is read as (S, A, K).
    """
    phi = numeric("features", np.asarray(raw["features"]))
    lead = phi.shape[:-1]
    if phi.ndim == 4 and lead == (T, S, A):
        fail(
            f"key 'features' has shape {phi.shape}, (T, S, A, K): features of a state and an action count at the T - 1 = {T - 1} "
            f"steps where an action is taken (the last state has none), so give (T-1, S, A, K) = ({T - 1}, {S}, {A}, {phi.shape[-1]})"
        )
    if lead not in ((S,), (S, A), (T, S), (T - 1, S, A)) or phi.shape[-1] < 1:
        fail(
            f"key 'features' must have shape (S, K), (S, A, K) for features of a state and an action, or with a first axis "
            f"for the step t: (T, S, K), (T-1, S, A, K); here S = {S}, A = {A} (from 'transitions'), T = {T} and K >= 1, "
            f"but it has shape {phi.shape}"
        )
    too_large("features", phi, T)
    if (lead == (S, A) or phi.ndim == 4) and "demo_actions" not in raw and "feature_expectations" not in raw:
        fail(
            "the features are of a state and an action, and the demonstrations have no actions: give "
            "'demo_actions' (the action at each step), or their feature expectations as 'feature_expectations'"
        )
    return phi


def too_large(key: str, x: np.ndarray, T: int) -> None:
    """Refuse values whose sums over the horizon may overflow the game's squares (``MAX_SUM``)."""
    total = largest_sum(x, T)
    if total > MAX_SUM:
        fail(
            f"key '{key}' reaches {np.max(np.abs(x)):.3g}: its sums over the T = {T} step{'s' if T != 1 else ''} (up to {total:.3g}) are beyond "
            f"{MAX_SUM:.0e}, where eq. 5.9's squares overflow; scale it down"
        )


def held_out_dynamics(raw: dict[str, np.ndarray], S: int, A: int) -> np.ndarray | SparseDynamics | None:
    """The held-out test dynamics (E, S, A, S) no demonstration came from, checked against the
    training dynamics' S and A; None when the file has none."""
    if not any(k in raw for k in TEST_KEYS):
        return None
    P = dynamics(raw, "test_")
    if P.shape[1:3] != (S, A):
        key = "test_transitions" if "test_transitions" in raw else "test_transition_probs"
        fail(f"key '{key}' must have S = {S} states and A = {A} actions as 'transitions' has, but has shape {np.shape(raw[key])}")
    return P


def sparse_keys(raw: dict[str, np.ndarray], prefix: str = "") -> SparseDynamics:
    """The dynamics of the sparse keys, kept sparse: next states (S, R) and their probabilities (M, S, A, R)."""
    nxt_key, probs_key = prefix + SPARSE_KEYS[0], prefix + SPARSE_KEYS[1]
    nxt = numeric(nxt_key, np.asarray(raw[nxt_key]), integer=True)
    probs = renormalised(np.asarray(raw[probs_key]), numeric(probs_key, np.asarray(raw[probs_key])))
    if nxt.ndim != 2 or nxt.shape[1] < 1:
        fail(f"key '{nxt_key}' must have shape (S, R) with R >= 1, but has shape {nxt.shape}")
    S, R = nxt.shape
    if probs.ndim != 4 or probs.shape[1] != S or probs.shape[3] != R:
        fail(f"key '{probs_key}' must have shape (M, S, A, R) = (M, {S}, A, {R}) (S, R from '{nxt_key}'), but has shape {probs.shape}")
    if nxt.min() < -1 or nxt.max() >= S:
        idx = tuple(int(i) for i in np.argwhere((nxt < -1) | (nxt >= S))[0])
        fail(f"key '{nxt_key}' has state index {nxt[idx]} at {idx}, outside [0, {S}) (-1 pads a row)")
    pad = np.broadcast_to(nxt[None, :, None, :] < 0, probs.shape)
    if np.any(probs[pad] != 0):
        j, s, a, r = (int(i) for i in np.argwhere(pad & (probs != 0))[0])
        fail(f"key '{probs_key}' gives probability {probs[j, s, a, r]:.3g} at {(j, s, a, r)} to a padding entry (-1) of '{nxt_key}'")
    keyed = np.where(nxt >= 0, nxt, -1 - np.arange(R)[None, :])  # padding entries never collide
    ordered = np.sort(keyed, axis=1)
    dup = np.argwhere(ordered[:, 1:] == ordered[:, :-1])
    if dup.size:
        s = int(dup[0, 0])
        fail(f"key '{nxt_key}' lists next state {ordered[s, dup[0, 1]]} twice in row {s}")
    return SparseDynamics(nxt, probs)


def demonstrations(raw: dict, P, p0: np.ndarray, T: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(demo_states (D, N, T), demo_actions (D, N, T-1)) checked against the dynamics: in range,
    starting where 'initial' is positive, every move possible (with its action, when given)."""
    M, S, A, _ = P.shape
    D = M - 1
    states = actions = None
    if "demo_states" in raw:
        states = numeric("demo_states", np.asarray(raw["demo_states"]), integer=True)
        if states.ndim != 3 or states.shape[0] != D or states.shape[2] != T or states.shape[1] < 1:
            fail(
                f"key 'demo_states' must have shape (D, N, T) = ({D}, N, {T}) with N >= 1 "
                f"(D from 'transitions', T from 'horizon'), but has shape {states.shape}"
            )
        if states.min() < 0 or states.max() >= S:
            idx = tuple(int(i) for i in np.argwhere((states < 0) | (states >= S))[0])
            fail(f"key 'demo_states' has state index {states[idx]} at {idx}, outside [0, {S})")
        starts = states[:, :, 0]
        if np.any(p0[starts] <= 0):
            j, n = (int(i) for i in np.argwhere(p0[starts] <= 0)[0])
            fail(f"key 'demo_states' has demonstration ({j}, {n}) start in state {starts[j, n]}, which 'initial' gives probability 0")
    if "demo_actions" in raw:
        assert states is not None
        actions = numeric("demo_actions", np.asarray(raw["demo_actions"]), integer=True)
        shape("demo_actions", actions, (D, states.shape[1], T - 1), "(D, N, T-1)")
        if actions.min() < 0 or actions.max() >= A:
            idx = tuple(int(i) for i in np.argwhere((actions < 0) | (actions >= A))[0])
            fail(f"key 'demo_actions' has action index {actions[idx]} at {idx}, outside [0, {A})")
    if states is None:
        return None, None
    j_idx = np.arange(1, M)[:, None, None]
    s, s_next = states[:, :, :-1], states[:, :, 1:]
    sparse = isinstance(P, SparseDynamics)
    if actions is not None:
        prob = P.probability(j_idx, s, actions, s_next) if sparse else P[j_idx, s, actions, s_next]
        what = "with the recorded action"
    else:
        if sparse:
            prob = np.max([P.probability(j_idx, s, a, s_next) for a in range(A)], axis=0)
        else:
            prob = P[j_idx, s, :, s_next].max(axis=-1)
        what = "under any action"
    if np.any(prob <= 0):
        j, n, t = (int(i) for i in np.argwhere(prob <= 0)[0])
        # name the key the file has: a sparse file gives its dynamics as 'transition_next' and 'transition_probs'
        where = f"'transition_next'/'transition_probs' (dynamics {j + 1})" if sparse else f"'transitions'[{j + 1}]"
        fail(
            f"key 'demo_states' has demonstration ({j}, {n}) move from state {s[j, n, t]} to {s_next[j, n, t]} "
            f"at step {t}, which {where} gives probability 0 {what}"
        )
    return states, actions


def optional_arrays(raw: dict, D: int, S: int, K: int, T: int) -> tuple:
    """(feature_expectations (D, K), true_weights (K,), loss (S, S)), each None when absent; T the horizon."""
    fexp = w_star = loss = None
    if "feature_expectations" in raw:
        fexp = numeric("feature_expectations", np.asarray(raw["feature_expectations"]))
        shape("feature_expectations", fexp, (D, K), "(D, K)")
        too_large("feature_expectations", fexp, 1)  # already sums over the horizon
    if "true_weights" in raw:
        w_star = numeric("true_weights", np.asarray(raw["true_weights"]))
        shape("true_weights", w_star, (K,), "(K,)")
    if "loss" in raw:
        loss = numeric("loss", np.asarray(raw["loss"]))
        shape("loss", loss, (S, S), "(S, S)")
        if np.any(loss < 0):
            idx = tuple(int(i) for i in np.argwhere(loss < 0)[0])
            fail(f"key 'loss' must be non-negative, but has {loss[idx]:.3g} at {idx}")
        too_large("loss", loss, T)
        if S > 1 and not np.any(loss):  # eq. 5.9 would then ask nothing of the learner's policy (one state has no other to differ from)
            fail("key 'loss' is zero everywhere, so the game (eq. 5.9) asks nothing of the learner's policy; drop the key for the config's loss, or give loss(ŝ, š) > 0 where the states differ")
    return fexp, w_star, loss


def discount_and_actions(raw: dict, S: int, A: int) -> tuple[float, np.ndarray | None]:
    """gamma (1 when absent) and the (S, A) bool allowed actions (None when absent)."""
    discount = 1.0
    if "discount" in raw:
        g = numeric("discount", np.asarray(raw["discount"]))
        if g.shape != () or not 0.0 < float(g) <= 1.0:
            fail(f"key 'discount' must be one number in (0, 1], but is {g.tolist()!r}")
        discount = float(g)
    allowed = None
    if "allowed_actions" in raw:
        allowed = np.asarray(raw["allowed_actions"])
        if allowed.dtype != bool:
            fail(f"key 'allowed_actions' must be a bool array, but is {allowed.dtype}")
        shape("allowed_actions", allowed, (S, A), "(S, A)")
        if not allowed.any(axis=1).all():
            fail(f"key 'allowed_actions' leaves state {int(np.argmin(allowed.any(axis=1)))} without an action")
    return discount, allowed


def demos_within(states: np.ndarray | None, actions: np.ndarray | None, allowed: np.ndarray | None) -> None:
    """Every demonstrated action is one that ``allowed`` (S, A) says exists in its state (states
    (D, N, T), actions (D, N, T-1); nothing to check without either)."""
    if allowed is None or actions is None:
        return
    taken = allowed[states[..., :-1], actions]
    if not taken.all():
        j, n, t = (int(i) for i in np.argwhere(~taken)[0])
        fail(f"key 'demo_actions' takes action {int(actions[j, n, t])} in state {int(states[j, n, t])} (dynamics {j + 1}, "
             f"demonstration {n}, step {t}), which 'allowed_actions' says does not exist there")


def expert_model(raw: dict) -> tuple[str, float | None]:
    """How the demonstrations' expert is modelled: 'expert' ("tau", the thesis's, when absent, or
    "own") and 'expert_beta' (a soft-optimal own expert's entropy weight > 0; None: hard)."""
    expert = "tau"
    if "expert" in raw:
        e = np.asarray(raw["expert"])
        if e.shape != () or e.dtype.kind != "U" or str(e) not in ("tau", "own"):
            fail(f"key 'expert' must be the string 'tau' or 'own', but is {e.tolist()!r}")
        expert = str(e)
    beta = None
    if "expert_beta" in raw:
        b = numeric("expert_beta", np.asarray(raw["expert_beta"]))
        if b.shape != () or not float(b) > 0.0:
            fail(f"key 'expert_beta' must be one number > 0, but is {b.tolist()!r}")
        if expert != "own":
            fail("key 'expert_beta' (a soft-optimal expert of each dynamics' own) needs 'expert' = 'own'")
        beta = float(b)
    return expert, beta


def environment_keys(raw: dict, S: int) -> tuple[np.ndarray | None, str | None, str | None]:
    """What a problem read from an environment says of itself: 'goal_states' (S,) bool (the states
    that reach its goal; 0/1 numbers are read as bool), 'environment' and 'perturbation' (one string
    each: where it comes from, how tau_1..tau_D were made); None for an absent key."""
    goal = None
    if "goal_states" in raw:
        g = np.asarray(raw["goal_states"])
        if g.dtype != bool:
            g = numeric("goal_states", g)
            if not np.all((g == 0) | (g == 1)):
                fail("key 'goal_states' must be true/false (or 0/1) per state")
        shape("goal_states", g, (S,), "(S,)")
        goal = g.astype(bool)
    texts = []
    for key in ("environment", "perturbation"):
        text = None
        if key in raw:
            e = np.asarray(raw[key])
            if e.shape != () or e.dtype.kind != "U":
                fail(f"key '{key}' must be one string, but is {e.dtype} with shape {e.shape}")
            text = str(e)
        texts.append(text)
    return goal, texts[0], texts[1]
