"""Exact evaluation of frozen option policies on a world's true model.

A *frozen* option policy chooses, at every non-terminal state ``s``, option ``o`` with a fixed
probability ``π(o | s)`` (a greedy policy: one option, or uniformly one of its tied options) and
runs it until it terminates (β), then chooses again. After an episode ends (a terminal state is
entered) the next one starts from a draw of the start distribution ``μ`` (``start_distribution``,
or ``start_state`` when the world has none), as the learner's runs do
(:class:`~himit_torch.Learner`: the step that enters the terminal state is the episode's last;
the next step is taken from the new start). On the SMDP that the options' exact models induce
(:func:`~himit_torch.exact.option_models.option_models_and_durations`), with ``P^o``/``r(s, o)``
the discounted models and ``Pr^o``/``D(s, o)`` the undiscounted termination probabilities and
expected durations, ``K_π = Σ_o π(o|·) Pr^o`` and ``d_π = Σ_o π(o|·) D(·, o)``:

* **V^π(start)** ``= Σ_s μ(s) V^π(s)`` with ``V^π = r_π + P_π V^π`` (``V = 0`` at terminal
  states), the world's discounted return of an episode (Sutton, Precup & Singh 1999).
* **Goal probability** ``h(μ) = Σ_s μ(s) h(s)``, ``h = K_π h`` on non-terminal states, ``h = 1``
  at goal states and ``0`` at other terminal states: the probability that an episode ends at a
  goal (:attr:`goal_mask <himit_torch.TableWorld.goal_mask>`; every terminal state for worlds
  without one, e.g. MultiRooms).
* **Steps per episode** ``E[T] = Σ_s μ(s) t(s)``, ``t = d_π + K_π t`` (``t = 0`` at terminal
  states): the expected number of primitive steps of an episode; ``inf`` when some episode may
  never end (a state the policy reaches from ``μ`` with positive probability from which no
  terminal state can be reached: a loop of decisions, or a state where it has no option).
* **Goals per window** ``W · h(μ) / E[T]``: the long-run number of goals per ``W`` primitive
  steps of the renewal process "episode after episode" (the renewal–reward theorem: episodes are
  independent and identically distributed, each lasting ``T`` steps and scoring ``1`` with
  probability ``h(μ)``). ``0`` when some episode may never end: the run is then stuck for good
  with probability 1 in the long run. For the optimal policy of a world with one start and one
  goal this is ``W / E[T]``, :meth:`~himit_torch.OptimalBaseline.goals_per`.
* **Reach share**: the ``μ``-weighted share of start states from which the policy reaches a goal
  with probability 1 (no state reachable from there is a non-goal terminal state or one from
  which no terminal can be reached); decided on the graph of possible transitions, exactly. With
  one start state (MultiRooms) it is 0 or 1. A world whose every policy risks a bad ending
  (FrozenLake's holes) has share 0 for every policy: read the goal probability there.

**A state the run has not tried.** A learner's frozen greedy policy
(:meth:`learner.views.greedy_policy <himit_torch.LearnerViews.greedy_policy>`) needs a rule for a
non-terminal state where the run has tried none of its options (no usable, i.e. tried and
enabled, option; a ``bco`` run's cloned action, where it has one there, counts as a choice). The
rule is a setting, ``untried`` (:data:`UNTRIED_RULES`):

* ``"uniform"`` (the default): what the learner itself does when it acts greedily there — it
  picks uniformly among the options available to it at that state (with ``tie_break="first"``:
  the first of them, the lowest). A run whose untried options are valued (a prior,
  ``concentration > 0``, or ``untried_value``) chooses by those values instead, as it acts.
* ``"stuck"``: such a state is never left — its row of ``π`` sums to 0. An episode that reaches
  it never ends: the goal rate is 0 and the steps per episode ``inf`` whenever one is reachable
  from ``μ``, and the goal probability counts only the episodes that end before reaching one.
  ``V^π`` gets no reward after it (``V = 0`` at a state without an option, as in ``V = r_π +
  P_π V`` with a zero row), so under this rule read the goal rate, not the value.

**The optimum and the value gap.** :func:`optimal_value` is ``V*(μ) = Σ_s μ(s) V*(s)``, the
optimal value over primitive actions on the true model (the exact value of the policy that value
iteration finds, :func:`optimal_policy_evaluation`); :meth:`PolicyEvaluation.value_gap` is
``V*(μ) − V^π(μ)`` of each run (≥ 0; 0 = optimal), the Gymnasium comparison's and the puzzle
box's greedy endpoint.

Every number comes from sparse LU solves of these linear systems, restricted to the states the
policy reaches from ``μ``, without iteration; no tolerance is involved beyond floating-point
round-off (relative errors ≈ 1e-12 on the paper's worlds; the tests compare with long Monte-Carlo
rollouts). The models assume each option runs until β stops it: the learner's safety net
``LearnerConfig.max_option_steps`` (100 000 steps by default) is not modelled.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import torch

from himit_torch.exact.option_models import OptionModels, option_models_and_durations
from himit_torch.exact.planning import PlanResult, reachable, smdp_value_iteration
from himit_torch.options.builders import primitive_options
from himit_torch.options.bundle import Options
from himit_torch.validation import COUNT_MAX, as_float, as_index_tensor, as_int

__all__ = [
    "GAP_ROUND_OFF",
    "UNTRIED_RULES",
    "OptionPolicy",
    "PolicyEvaluation",
    "PolicyEvaluator",
    "check_untried_rule",
    "evaluate_option_choice",
    "optimal_policy_evaluation",
    "optimal_value",
]

#: The rules for a state where a run has tried none of its options (module docstring):
#: ``"uniform"`` (the default, as the learner acts) and ``"stuck"`` (never left).
UNTRIED_RULES = ("uniform", "stuck")

#: A value gap this small is the solvers' round-off, not a worse policy: reported as 0.
GAP_ROUND_OFF = 1e-9

#: Transition probabilities of a policy's chain below this are round-off of the option models'
#: solve, dropped before the goal probabilities and expected steps are solved.
ROUND_OFF = 1e-12


@dataclass(frozen=True)
class OptionPolicy:
    """A frozen (stationary, possibly stochastic) option policy for each of ``B`` runs.

    Attributes:
        option: ``[S, J]`` int64, the candidate options of each state (−1: an unused slot);
            shared by the runs (e.g. a learner's rows at each state).
        probability: ``[B, S, J]`` float64, ``π_b(option[s, j] | s)``; each state's row sums to
            1, or to 0 where the run has no option (it would stay there forever).

    Raises:
        TypeError: ``option`` or ``probability`` is no tensor (a NumPy array, a list).
        ValueError: shapes or dtypes other than these (complex, integer or bool
            probabilities), an option below −1, or rows that are not probabilities.
    """

    option: torch.Tensor
    probability: torch.Tensor

    def __post_init__(self):
        for name in ("option", "probability"):
            value = getattr(self, name)
            if not isinstance(value, torch.Tensor):
                raise TypeError(
                    f"OptionPolicy.{name} must be a tensor, got {type(value).__name__} (give "
                    "torch.as_tensor(...), or OptionPolicy.deterministic(choice))"
                )
        if self.option.dim() != 2 or self.option.dtype != torch.int64:
            raise ValueError(
                f"OptionPolicy.option must be [S, J] int64, got {tuple(self.option.shape)} "
                f"{self.option.dtype}"
            )
        if self.probability.dim() != 3 or self.probability.shape[1:] != self.option.shape:
            raise ValueError(
                f"OptionPolicy.probability must be [B, S, J] = [B, {self.option.shape[0]}, "
                f"{self.option.shape[1]}], got {tuple(self.probability.shape)}"
            )
        p = self.probability
        if not p.dtype.is_floating_point:
            raise ValueError(
                f"OptionPolicy.probability must be real (float64) probabilities, got {p.dtype}"
            )
        if self.option.numel() and int(self.option.min()) < -1:
            raise ValueError(
                f"OptionPolicy.option holds {int(self.option.min())}: options are 0 … J − 1, "
                "and −1 marks an unused slot"
            )
        sums = p.sum(-1)
        if (
            not bool(torch.isfinite(p).all())
            or bool((p < 0).any())
            or not bool(((sums - 1).abs() < 1e-9).logical_or(sums == 0).all())
        ):
            raise ValueError(
                "OptionPolicy.probability must be ≥ 0 and sum to 1 (or 0: no option) at every state"
            )
        if bool(((p > 0) & (self.option < 0)).any()):
            raise ValueError("OptionPolicy puts probability on an unused slot (option −1)")

    @classmethod
    def deterministic(cls, option: torch.Tensor) -> OptionPolicy:
        """The policy that takes ``option [S]`` (one run) or ``[B, S]`` at each state (−1: no
        option there)."""
        option = as_index_tensor("OptionPolicy.deterministic: option", option, -1).cpu()
        if option.dim() == 1:
            option = option[None]
        if option.dim() != 2:
            raise ValueError(f"option must be [S] or [B, S], got {tuple(option.shape)}")
        B, S = option.shape
        if B == 1:
            return cls(option[0][:, None], (option >= 0).double()[..., None])
        # One slot per distinct option of a state across the runs.
        table = torch.sort(option, 0).values
        keep = torch.ones_like(table, dtype=torch.bool)
        keep[1:] = table[1:] != table[:-1]
        keep &= table >= 0
        slot = keep.long().cumsum(0) - 1
        J = max(1, int(keep.sum(0).max()))
        slots = torch.full((S, J), -1, dtype=torch.int64)
        cols = torch.arange(S).expand(B, S)
        slots[cols[keep], slot[keep]] = table[keep]
        probability = (slots[None] == option[..., None]) & (option[..., None] >= 0)
        return cls(slots, probability.double())

    @property
    def batch(self) -> int:
        return self.probability.shape[0]

    @property
    def num_states(self) -> int:
        return self.option.shape[0]


@dataclass(frozen=True)
class PolicyEvaluation:
    """What ``B`` frozen option policies achieve, exactly (module docstring for definitions).

    Attributes (each ``[B]`` float64):
        value_start: ``V^π(start)``, expected over the start distribution.
        goal_probability: probability that an episode ends at a goal.
        steps_per_episode: expected primitive steps of an episode (``inf``: some may never end).
        goals_per_window: long-run goals per ``window`` steps (``0``: some episode may never end).
        reach_share: ``μ``-weighted share of start states from which a goal is certain.
        window: ``W``, the steps of a window.
    """

    value_start: torch.Tensor
    goal_probability: torch.Tensor
    steps_per_episode: torch.Tensor
    goals_per_window: torch.Tensor
    reach_share: torch.Tensor
    window: int

    def percent_of(self, goals_per_window: float | torch.Tensor) -> torch.Tensor:
        """``[B]`` goals per window as a percentage of a reference rate (the optimum's, the
        mentor's); NaN where the reference is 0."""
        if isinstance(goals_per_window, torch.Tensor):
            if not goals_per_window.dtype.is_floating_point:
                raise ValueError(
                    "PolicyEvaluation.percent_of: goals_per_window must be real, got a "
                    f"{goals_per_window.dtype} tensor"
                )
        else:
            goals_per_window = as_float("PolicyEvaluation.percent_of: goals_per_window",
                                        goals_per_window, 0.0)  # fmt: skip
        ref = torch.as_tensor(goals_per_window, dtype=torch.float64)
        return torch.where(
            ref > 0, 100.0 * self.goals_per_window / ref, torch.full_like(ref, float("nan"))
        )

    def value_gap(self, optimal_value: float) -> torch.Tensor:
        """``[B]`` ``V*(μ) − V^π(μ)`` (``optimal_value``: ``V*(μ)``, :func:`optimal_value`); 0 =
        optimal, and a gap within :data:`GAP_ROUND_OFF` of 0 is 0. NaN where the value was not
        solved (``evaluate(values=False)``)."""
        gap = (
            as_float("PolicyEvaluation.value_gap: optimal_value", optimal_value) - self.value_start
        )
        return torch.where(gap.abs() < GAP_ROUND_OFF, torch.zeros_like(gap), gap)

    def __len__(self) -> int:
        return self.value_start.shape[0]


def check_untried_rule(untried: str) -> str:
    """``untried`` if it names a rule of :data:`UNTRIED_RULES`.

    Raises:
        ValueError: naming the value and the rules.
    """
    if untried not in UNTRIED_RULES:
        raise ValueError(f"untried={untried!r}: use one of {UNTRIED_RULES}")
    return untried


def _check_world(where: str, world) -> None:
    """A ``TypeError`` naming ``where`` unless ``world`` is a world with a true model (``None``,
    a string, a path are no world)."""
    missing = [m for m in ("num_states", "terminal_mask", "gamma") if not hasattr(world, m)]
    if missing:
        raise TypeError(
            f"{where}: world must be a world with a true model (num_states, "
            f"terminal_mask, gamma, …), got {type(world).__name__} (lacks {missing})"
        )


def _check_options(where: str, options) -> None:
    if not isinstance(options, Options):
        raise TypeError(
            f"{where}: options must be an Options bundle (e.g. "
            f"primitive_options(world)), got {type(options).__name__}"
        )


def _scipy_csr(t: torch.Tensor) -> sp.csr_matrix:
    c = t.to_sparse_csr() if t.layout != torch.sparse_csr else t
    return sp.csr_matrix(
        (c.values().numpy(), c.col_indices().numpy(), c.crow_indices().numpy()),
        shape=tuple(c.shape),
    )


def _models_of(options: Options, models) -> tuple[OptionModels, OptionModels]:
    """``models`` as ``(discounted, durations)`` after checking that both are models of
    ``options``: their rows are its available ``(s, o)``, option by option (the rows
    :func:`~himit_torch.exact.option_models.option_models_and_durations` builds)."""
    if (
        not isinstance(models, (tuple, list))
        or len(models) != 2
        or not all(isinstance(m, OptionModels) for m in models)
    ):
        raise TypeError(
            "PolicyEvaluator: models must be the (discounted, durations) pair of "
            "option_models_and_durations(world, options), got "
            f"{type(models).__name__}"
        )
    pairs = options.initiation.nonzero()  # [M, 2] (o, s), option by option as the rows are
    for name, model in zip(("discounted", "durations"), models):
        same = (
            model.num_options == options.num_options
            and model.num_states == options.num_states
            and model.num_rows == pairs.shape[0]
            and torch.equal(model.row_option.cpu(), pairs[:, 0].cpu())
            and torch.equal(model.row_state.cpu(), pairs[:, 1].cpu())
        )
        if not same:
            raise ValueError(
                f"PolicyEvaluator: models ({name}) are not models of these options: they hold "
                f"{model.num_rows} rows of {model.num_options} options over {model.num_states} "
                f"states, where the options have {pairs.shape[0]} available (state, option) pairs "
                f"of {options.num_options} options over {options.num_states} states; give the "
                "models of the same bundle (option_models_and_durations(world, options)) or "
                "leave models out"
            )
    return models[0], models[1]


class PolicyEvaluator:
    """Evaluates frozen policies over ``options`` in ``world``, exactly (module docstring).

    Builds the options' exact discounted and undiscounted models once (the costly part: ≈ 1 s
    on the 80×80 world with corner options); each :meth:`evaluate` then solves per run.

    Args:
        world: a world with a true model (``transition_model``/``reward_model`` or a
            ``dynamics_table``), ``terminal_mask``, ``gamma`` and ``start_state`` or
            ``start_distribution``.
        options: the options the policies choose among.
        window: ``W``, steps per window of ``PolicyEvaluation.goals_per_window``.
        goal_mask: ``[S]`` bool, the terminal states that count as goals; by default the world's
            ``goal_mask`` where it has one, else every terminal state.
        models: ``(discounted, durations)`` of ``options`` if already computed
            (:func:`~himit_torch.exact.option_models.option_models_and_durations`).

    Raises:
        TypeError: ``world`` is no world (``num_states``, ``terminal_mask``, ``gamma``), or
            ``options`` no :class:`~himit_torch.Options`.
        ValueError: ``window`` not a whole number in ``1 … COUNT_MAX`` (``2.5``, ``"500"`` and
            ``True`` are refused, never read as a window), options over another number of
            states, ``models`` not the two models of ``options`` (another bundle's: other
            options or initiation sets), or a bad ``goal_mask``.
    """

    def __init__(
        self,
        world,
        options: Options,
        window: int,
        goal_mask: torch.Tensor | None = None,
        models: tuple[OptionModels, OptionModels] | None = None,
    ):
        _check_world("PolicyEvaluator", world)
        _check_options("PolicyEvaluator", options)
        window = as_int("PolicyEvaluator: window", window, 1, COUNT_MAX)
        S = int(world.num_states)
        if options.num_states != S:
            raise ValueError(f"options are over {options.num_states} states but the world has {S}")
        self.world, self.options, self.window = world, options, int(window)
        self.num_states, self.gamma = S, float(world.gamma)
        discounted, durations = (
            option_models_and_durations(world, options)
            if models is None
            else _models_of(options, models)
        )
        self.terminal = torch.as_tensor(world.terminal_mask, dtype=torch.bool).cpu().numpy()
        if goal_mask is None:
            goal_mask = getattr(world, "goal_mask", None)
        goal = self.terminal if goal_mask is None else torch.as_tensor(goal_mask).cpu().numpy()
        if goal.shape != (S,) or goal.dtype != bool:
            raise ValueError(f"goal_mask must be a [S] = [{S}] bool tensor")
        if (goal & ~self.terminal).any():
            raise ValueError("goal_mask marks non-terminal states: a goal must end the episode")
        self.goal = goal
        self._goal_states = np.flatnonzero(goal)
        start = getattr(world, "start_distribution", None)
        if start is None:
            mu = np.zeros(S)
            mu[int(world.start_state)] = 1.0
        else:
            mu = torch.as_tensor(start, dtype=torch.float64).cpu().numpy()
        self.start = mu
        self.sources = np.flatnonzero(mu > 0)
        self.P_disc, self.r_disc = _scipy_csr(discounted.transition), discounted.reward.numpy()
        self.P_prob, self.duration = _scipy_csr(durations.transition), durations.reward.numpy()
        key = (discounted.row_state * options.num_options + discounted.row_option).numpy()
        self._order = np.argsort(key, kind="stable")
        self._keys = key[self._order]

    def model_rows(self, option: torch.Tensor) -> np.ndarray:
        """``[S, J]`` the model row of ``(s, option[s, j])`` (−1: unused slot or unavailable)."""
        checked = as_index_tensor("PolicyEvaluator.model_rows: option", option, -1, dim=2)
        table = checked.cpu().numpy()
        S, J = table.shape
        key = np.arange(S)[:, None] * self.options.num_options + np.maximum(table, 0)
        pos = np.searchsorted(self._keys, key).clip(max=max(self._keys.size - 1, 0))
        found = (table >= 0) & (self._keys[pos] == key)
        return np.where(found, self._order[pos], -1)

    def evaluate(self, policy: OptionPolicy, values: bool = True) -> PolicyEvaluation:
        """:class:`PolicyEvaluation` of each run of ``policy`` (over this evaluator's options).

        ``values=False`` leaves ``value_start`` NaN and skips its solve (half the time): for
        evaluations that need only the goal rate.

        Raises:
            TypeError: ``policy`` is not an :class:`OptionPolicy`.
            ValueError: the policy is over another number of states, names an option that does
                not exist, or puts probability on an option unavailable at its state.
        """
        if not isinstance(policy, OptionPolicy):
            raise TypeError(
                f"PolicyEvaluator.evaluate: policy must be an OptionPolicy (e.g. "
                f"learner.views.greedy_policy() or OptionPolicy.deterministic(choice)), got "
                f"{type(policy).__name__}"
            )
        if policy.num_states != self.num_states:
            raise ValueError(
                f"the policy is over {policy.num_states} states but the world has {self.num_states}"
            )
        if bool((policy.option >= self.options.num_options).any()):
            raise ValueError(
                f"the policy names option {int(policy.option.max())} but there are "
                f"{self.options.num_options} options"
            )
        rows = self.model_rows(policy.option)
        prob = policy.probability.cpu().numpy()
        out = np.array([self._evaluate_one(rows, prob[b], values) for b in range(policy.batch)])
        out = out.reshape(policy.batch, 5)
        value, goal_p, steps, rate, share = (torch.from_numpy(out[:, i].copy()) for i in range(5))
        return PolicyEvaluation(value, goal_p, steps, rate, share, self.window)

    def _evaluate_one(self, rows: np.ndarray, prob: np.ndarray, values: bool) -> tuple:
        S, M = self.num_states, self.P_prob.shape[0]
        chosen = (prob > 0) & ~self.terminal[:, None]
        if (rows[chosen] < 0).any():
            s, j = np.argwhere(chosen & (rows < 0))[0]
            raise ValueError(f"the policy chooses an option at state {s} where it is unavailable")
        s_idx, j_idx = np.nonzero(chosen)
        choice = sp.csr_matrix((prob[s_idx, j_idx], (s_idx, rows[s_idx, j_idx])), shape=(S, M))
        K = (choice @ self.P_prob).tocsr()
        # Round-off of the option models' solve (|p| ~ 1e-17, either sign) is not a way out:
        # kept, it makes a closed set of states look as if it could end, and its near-singular
        # system fails to factor (seen on FrozenLake 8×8 with first-index ties).
        K.data[np.abs(K.data) < ROUND_OFF] = 0.0
        K.eliminate_zeros()
        reach = reachable(K, self.sources)
        live = np.flatnonzero(reach & ~self.terminal)
        back = K.T.tocsr()  # predecessors
        can_end = reachable(back, np.flatnonzero(reach & self.terminal))
        doomed = live[~can_end[live]]
        ends = live[can_end[live]]
        # A goal is certain from s unless s can reach a doomed state or a non-goal ending.
        bad = np.concatenate([doomed, np.flatnonzero(reach & self.terminal & ~self.goal)])
        unsure = reachable(back, bad)
        mu = self.start
        share = float(mu[self.sources][~unsure[self.sources]].sum())
        # Undiscounted: goal probabilities and expected steps on the states that can end.
        h = np.zeros(S)
        t = np.zeros(S)
        if ends.size:
            K_e = K[ends]
            system = sp.identity(ends.size, format="csc") - K_e[:, ends].tocsc()
            into_goal = np.asarray(K_e[:, self._goal_states].sum(1)).ravel()
            rhs = np.stack([into_goal, choice[ends] @ self.duration], 1)
            sol = spla.splu(system).solve(rhs)
            h[ends], t[ends] = sol[:, 0], sol[:, 1]
        goal_p = float(mu @ h)
        if doomed.size:
            steps, rate = float("inf"), 0.0
        else:
            steps = float(mu @ t)
            rate = self.window * goal_p / steps
        # Discounted value on every reached non-terminal state (singular only for γ = 1 with
        # doomed states: their value is undefined then).
        if not values or (self.gamma >= 1.0 and doomed.size):
            value = float("nan")
        elif live.size:
            K_d = (choice[live] @ self.P_disc).tocsr()[:, live]
            system = sp.identity(live.size, format="csc") - K_d.tocsc()
            V = spla.splu(system).solve(choice[live] @ self.r_disc)
            value = float(mu[live] @ V)
        else:
            value = 0.0
        return value, goal_p, steps, rate, share


def evaluate_option_choice(
    world,
    options: Options,
    option: torch.Tensor,
    window: int,
    goal_mask: torch.Tensor | None = None,
) -> PolicyEvaluation:
    """Exact :class:`PolicyEvaluation` of one deterministic option policy ``option [S]`` over
    ``options`` (−1 where it has none), e.g. the mentor's :attr:`MentorPolicy.option
    <himit_torch.MentorPolicy.option>`. Only the options it chooses somewhere are modelled (the
    mentor of the 80×80 world with corner options: 501 of its 1164; with the slip it reaches
    every one of them from its start).

    Raises:
        TypeError: ``world`` is no world with a true model (``None``, a string), or ``options``
            no :class:`~himit_torch.Options`.
        ValueError: ``option`` not ``[S]`` whole numbers in ``−1 … J − 1`` (``NaN``, ``0.5`` and
            bools are refused, never cast), or a bad ``window``.
    """
    _check_world("evaluate_option_choice", world)
    _check_options("evaluate_option_choice", options)
    option = as_index_tensor("evaluate_option_choice: option", option, -1, dim=1).cpu()
    if option.shape != (int(world.num_states),):
        raise ValueError(f"option must be [S] = [{world.num_states}], got {tuple(option.shape)}")
    if int(option.max()) >= options.num_options:
        raise ValueError(
            f"option holds {int(option.max())} but there are {options.num_options} options"
        )
    used = torch.unique(option[option >= 0])
    if used.numel() == 0:  # no option anywhere: nothing to model, the run is stuck
        used = torch.zeros(1, dtype=torch.int64)
    local = torch.full((options.num_options,), -1, dtype=torch.int64)
    local[used] = torch.arange(used.numel())
    evaluator = PolicyEvaluator(world, options.select(used), window, goal_mask)
    return evaluator.evaluate(
        OptionPolicy.deterministic(torch.where(option >= 0, local[option.clamp(min=0)], -1))
    )


def optimal_policy_evaluation(
    world,
    window: int,
    goal_mask: torch.Tensor | None = None,
    models: Sequence[OptionModels] | None = None,
    plan: PlanResult | None = None,
) -> PolicyEvaluation:
    """:class:`PolicyEvaluation` (one run) of the optimal policy over primitive actions (SMDP
    value iteration on the primitive options' exact models, tolerance 1e-10,
    :func:`~himit_torch.exact.planning.smdp_value_iteration`; ties to the lowest action): the
    reference of "% of optimum". ``models``: the primitive options' ``(discounted, durations)``
    models, ``plan``: that value iteration's result, if already computed.

    Raises:
        TypeError: ``world`` is no world with a true model, ``plan`` no
            :class:`~himit_torch.exact.planning.PlanResult`, ``models`` not the primitives'
            ``(discounted, durations)`` pair.
        ValueError: ``window`` not a whole number in ``1 … COUNT_MAX``.
    """
    _check_world("optimal_policy_evaluation", world)
    window = as_int("optimal_policy_evaluation: window", window, 1, COUNT_MAX)
    if plan is not None and not isinstance(plan, PlanResult):
        raise TypeError(
            "optimal_policy_evaluation: plan must be the PlanResult of smdp_value_iteration, "
            f"got {type(plan).__name__}"
        )
    prims = primitive_options(world)
    discounted, durations = (
        option_models_and_durations(world, prims) if models is None else _models_of(prims, models)
    )
    if plan is None:
        plan = smdp_value_iteration(discounted)
    evaluator = PolicyEvaluator(world, prims, window, goal_mask, (discounted, durations))
    return evaluator.evaluate(OptionPolicy.deterministic(plan.policy))


def optimal_value(
    world,
    models: Sequence[OptionModels] | None = None,
    plan: PlanResult | None = None,
) -> float:
    """``V*(μ) = Σ_s μ(s) V*(s)``: the optimal value from the start distribution (``start_state``
    where the world has none), over primitive actions on the true model — the exact value of the
    policy that value iteration finds (:func:`optimal_policy_evaluation`, which takes the same
    ``models`` and ``plan``), so that the optimal policy's own
    :meth:`~PolicyEvaluation.value_gap` is 0 to round-off."""
    _check_world("optimal_value", world)
    evaluation = optimal_policy_evaluation(world, 1, models=models, plan=plan)
    return float(evaluation.value_start[0])
