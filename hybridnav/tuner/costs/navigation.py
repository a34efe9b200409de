"""Tuning a navigation controller on worlds: :class:`NavigationCost`.

Every (candidate, world, repeat) is simulated in lockstep: each control cycle is one batched fuzzy
evaluation for all robots of the chunk, one batched nearest-obstacle query over all worlds and one
batched model step — no Python loop per candidate, per world or per step.

The planner names the fuzzy inputs it provides (``Planner.fuzzy_inputs``; EFFC: ``dtheta``,
``alpha``) and its lockstep controller (``Planner.lockstep``); any planner that has both can be
tuned. The cost of one run (``reward.kind``):

``"deploy"`` (default)
    reached: ``length * L / D + time * T v / D + clearance * max(0, 1 - c / s)``, with ``L`` the
    path length, ``T`` the time to goal, ``v`` the planner speed, ``D`` the start-goal distance
    less the goal radius, ``c`` the run's minimum clearance and ``s = safety_distance`` robot
    radii; collided or out of bounds: ``collision``; stuck or timeout: ``failure + progress *
    min(1, d_end / d_start)``. The objective is the **mean** over worlds (each averaged over
    ``repeats``) plus the coverage penalty.
``"length"``
    the path length when the target is reached, else ``penalty``; summed.
``"paper"``
    the EFFC paper's literal convention: the distance on success, ``-penalty`` on failure, summed
    and *maximized* (the objective is its negative; reports show the paper's sign). Maximizing
    it rewards long detours: it is here so that its effect can be seen.

**Coverage.** A system must not rely on the "no rule fired" ``default``: the fraction of a
``coverage.grid``-per-axis grid over the input ranges where no rule fires is measured for every
candidate; the objective is worsened by ``coverage.penalty`` times its excess over
``coverage.max_uncovered``, and a candidate above ``max_uncovered`` is infeasible (a validation
choice never prefers it).

**Noise.** With ``heading_noise``, ``dtheta_noise`` or ``alpha_noise`` > 0, every cycle the
commanded heading is rotated by ``N(0, heading_noise)``, ``dtheta`` gets ``N(0, dtheta_noise)``
added and ``alpha`` is scaled by ``1 + N(0, alpha_noise)`` — each training run drawing from
``SeedSequence(seed, spawn_key=(generation, index, world, repeat))``, so results do not depend on
chunking or workers; validation and test runs use one fixed stream per (world, repeat), the same
for every candidate (common random numbers).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from hybridnav import models
from hybridnav.errors import HybridnavError
from hybridnav.params import Param
from hybridnav.tuner.costs.base import (
    Candidates,
    Context,
    Cost,
    Evaluation,
    fold_of,
    process_cache,
)

__all__ = ["COVERAGE", "MEASURES", "PLANNER", "REWARD", "VALIDATION_KEY", "NavigationCost"]

#: What a navigation objective can measure (several: a multi-objective cost for NSGA2). Each is
#: minimized, and each gets the coverage penalty added.
MEASURES = {
    "reward": "the reward of reward.kind (the paper reward's negative)",
    "failure": "fraction of runs that do not reach the goal",
    "collision": "fraction of runs that collide or leave the workspace",
    "length": "mean path length / start-goal distance over the runs that reach (inf: none)",
    "clearance": "minus the smallest clearance of any run (m): larger clearance is better",
}

#: First spawn-key entry of the validation noise streams (training uses the generation there).
VALIDATION_KEY = 2**31 - 1

_POS = {"lo": 0.0}

#: The reward settings (a job file's ``[reward]``).
REWARD: dict[str, Param] = {
    "kind": Param("deploy", "deploy, length or paper", choices=("deploy", "length", "paper")),
    "sense": Param("minimize", "minimize (maximize: kind = paper only)",
                   choices=("minimize", "maximize")),
    "penalty": Param(100.0, "kind = length / paper: a failed run's cost", **_POS),
    "collision": Param(20.0, "a collision or leaving the workspace", **_POS),
    "failure": Param(10.0, "stuck or timeout ...", **_POS),
    "progress": Param(5.0, "... plus this times distance left / start distance", **_POS),
    "length": Param(1.0, "times path length / start-goal distance, when reached", **_POS),
    "time": Param(0.0, "times time x speed / start-goal distance, when reached", **_POS),
    "clearance": Param(2.0, "times the shortfall of the minimum clearance below "
                            "safety_distance", **_POS),
    "safety_distance": Param(1.0, "in robot radii", **_POS),
    "repeats": Param(1, "noisy simulations per world, averaged (> 1 needs noise)", lo=1,
                     hi=1000),
    "heading_noise": Param(0.0, "std of the noise on the commanded heading (rad)", **_POS),
    "dtheta_noise": Param(0.0, "std of the noise added to dtheta (rad)", **_POS),
    "alpha_noise": Param(0.0, "std of the relative noise on alpha", **_POS),
}

#: The coverage settings (``[coverage]``).
COVERAGE: dict[str, Param] = {
    "grid": Param(41, "points per input axis", lo=2, hi=1001),
    "max_uncovered": Param(0.0, "largest allowed fraction where no rule fires", lo=0.0, hi=1.0),
    "penalty": Param(100.0, "cost per uncovered fraction beyond it", **_POS),
}

#: The simulation settings of the tuned planner (``[planner]``).
PLANNER: dict[str, Param] = {
    "speed": Param(0.1, "robot speed (m/s)", lo=0.0, lo_open=True),
    "max_turn": Param(math.pi / 4, "largest heading change per control cycle (rad)",
                      lo=0.0, lo_open=True, hi=math.pi),
    "stuck_window": Param(10.0, "seconds without progress that count as stuck", **_POS),
    "stuck_radius": Param(2.0, "the no-progress disk, in goal radii", **_POS),
    "safety_margin": Param(0.05, "room (m, beyond the robot radius) the escape-circle safety "
                                 "filter keeps (0: off; hybridnav.planners.field.safety)", **_POS),
}


def _settings(spec: dict[str, Param], given: Mapping[str, Any] | None, what: str
              ) -> dict[str, Any]:
    out = {k: p.default for k, p in spec.items()}
    for k, v in (given or {}).items():
        if k not in spec:
            raise HybridnavError(f"{what}.{k}: unknown key; expected one of: "
                                 f"{', '.join(sorted(spec))}")
        out[k] = spec[k].check(f"{what}.{k}", v)
    return out


class NavigationCost(Cost):
    """The navigation reward of a fuzzy controller on a set of worlds.

    Parameters
    ----------
    scenarios : sequence of Scenario
        Single-robot worlds with a fixed goal, one robot model for all (same ``dt``, radius and
        parameters), as :class:`hybridnav.world.Scenario` objects.
    planner : str
        A planner that takes a fuzzy system (``fuzzy_inputs`` and ``lockstep``): ``"effc"``.
    planner_params : mapping, optional
        ``speed``, ``max_turn``, ``stuck_window``, ``stuck_radius`` (:data:`PLANNER`).
    reward : mapping, optional
        :data:`REWARD` settings (default: the deploy reward).
    coverage : mapping, optional
        :data:`COVERAGE` settings.
    name : str, optional
        The set's name in reports (``train``, ``validation``, ...).
    objectives : sequence of str
        What is minimized, one or several of :data:`MEASURES` (default the reward; e.g.
        ``("failure", "length", "clearance")`` for NSGA2).
    strict : bool
        False: accept worlds the lockstep simulation cannot batch (several robots, other
        models) — such a cost can only :meth:`judge` (run by run with the planner).
    """

    def __init__(self, scenarios: Sequence, *, planner: str = "effc",
                 planner_params: Mapping[str, Any] | None = None,
                 reward: Mapping[str, Any] | None = None,
                 coverage: Mapping[str, Any] | None = None, name: str = "worlds",
                 strict: bool = True, objectives: Sequence[str] = ("reward",)) -> None:
        super().__init__()
        from hybridnav import planners

        from hybridnav.world import Scenario, load_scenario

        if isinstance(scenarios, (str, Scenario)):
            scenarios = [scenarios]
        loaded = []
        for i, s in enumerate(scenarios):
            if isinstance(s, str):             # a built-in name or a scenario file
                try:
                    s = load_scenario(s)
                except HybridnavError as exc:
                    raise HybridnavError(f"{name}[{i}]: {exc}") from None
            elif not isinstance(s, Scenario):
                raise HybridnavError(f"{name}[{i}]: expected a Scenario or a scenario name, got "
                                     f"{type(s).__name__}")
            loaded.append(s)
        self.scenarios = loaded
        self.name = name
        if planner not in planners.PLANNERS or not hasattr(planners.PLANNERS[planner],
                                                           "fuzzy_inputs"):
            fuzzy = [k for k, c in planners.PLANNERS.items() if hasattr(c, "fuzzy_inputs")]
            raise HybridnavError(f"planner: expected a planner that takes a fuzzy system "
                                 f"({', '.join(fuzzy)}), got {planner!r}")
        self.planner = planner
        self.planner_params = _settings(PLANNER, planner_params, "planner")
        self.reward = _settings(REWARD, reward, "reward")
        if self.reward["kind"] == "paper":
            self.reward["sense"] = "maximize"
        elif self.reward["sense"] == "maximize":
            raise HybridnavError("reward.sense: expected minimize for reward.kind = "
                                 f"{self.reward['kind']!r} (maximize is the paper's convention, "
                                 "reward.kind = 'paper')")
        noisy = any(self.reward[k] > 0 for k in ("heading_noise", "dtheta_noise", "alpha_noise"))
        if self.reward["repeats"] > 1 and not noisy:
            raise HybridnavError("reward.repeats: repeats > 1 only make sense with heading_noise, "
                                 "dtheta_noise or alpha_noise > 0 (without noise every repeat "
                                 "is identical)")
        if planner != "effc" and (self.reward["dtheta_noise"] > 0
                                  or self.reward["alpha_noise"] > 0):
            raise HybridnavError(f"reward.dtheta_noise, reward.alpha_noise: noise on EFFC's "
                                 f"inputs; the {planner} planner takes heading_noise only")
        self.coverage = _settings(COVERAGE, coverage, "coverage")
        if isinstance(objectives, str) or not objectives or \
                any(o not in MEASURES for o in objectives) or len(set(objectives)) < len(
                    objectives):
            raise HybridnavError(f"objectives: expected distinct names of {', '.join(MEASURES)}"
                                 f", got {objectives!r}")
        self.objectives_measured = tuple(objectives)
        self.objective_names = tuple(f"{self.reward['kind']} reward" if o == "reward" else o
                                     for o in objectives)
        if not self.scenarios:
            raise HybridnavError(f"{name}: expected at least one world")
        self.strict = strict
        if not strict:
            return
        for i, s in enumerate(self.scenarios):
            if (len(s.robots) != 1 or s.robots[0].goal is None
                    or "heading_control" not in models.MODELS[s.robots[0].model].capabilities):
                raise HybridnavError(f"{name}[{i}]: {s.source or s.name}: expected a scenario "
                                     "with exactly one unicycle robot and a fixed goal")
        keys = {(s.dt, s.robots[0].radius, tuple(sorted(s.robots[0].params.items())))
                for s in self.scenarios}
        if len(keys) > 1:
            raise HybridnavError(f"{name}: expected one robot model for the whole set (the same "
                                 "dt, robot radius and parameters), so that one batched step "
                                 f"serves them all; got {len(keys)} different ones")

    # ---- description -----------------------------------------------------------------------

    @property
    def fuzzy_inputs(self) -> tuple[str, ...]:
        """The fuzzy inputs the planner provides."""
        from hybridnav import planners

        return tuple(planners.PLANNERS[self.planner].fuzzy_inputs)

    @property
    def robot_radius(self) -> float:
        return float(self.scenarios[0].robots[0].radius)

    def check(self, settings) -> None:
        from hybridnav import planners
        from hybridnav.planners.base import accepts_inputs, inputs_text

        names = settings.template.input_names
        cls = planners.PLANNERS[self.planner]
        if not accepts_inputs(cls, names):
            raise HybridnavError(f"the {self.planner} planner provides the fuzzy inputs "
                                 f"{inputs_text(cls)}; {settings.template.name!r} "
                                 f"has {', '.join(names)}")

    def config(self) -> dict[str, Any]:
        from hybridnav.world import scenario_to_dict

        return {"kind": "navigation", "planner": self.planner,
                "objectives": list(self.objectives_measured),
                "planner_params": self.planner_params, "reward": self.reward,
                "coverage": self.coverage,
                "worlds": [scenario_to_dict(s) for s in self.scenarios]}

    def describe(self) -> str:
        what = (f"the {self.reward['kind']} reward" if self.objectives_measured == ("reward",)
                else "the objectives " + ", ".join(self.objective_names))
        margin = self.planner_params.get("safety_margin", 0.0)
        return (f"{what} of the {self.planner} planner on {len(self.scenarios)} worlds"
                + (f", with its escape-circle safety filter at safety_margin = {margin:g} (deploy "
                   "it with that setting)" if margin else ""))

    def with_scenarios(self, scenarios: Sequence, name: str) -> NavigationCost:
        """The same cost on other worlds."""
        return NavigationCost(scenarios, planner=self.planner,
                              planner_params=self.planner_params,
                              reward={k: v for k, v in self.reward.items() if k != "sense"}
                              | ({"sense": "minimize"} if self.reward["kind"] != "paper" else {}),
                              coverage=self.coverage, name=name,
                              objectives=self.objectives_measured)

    def folds(self, k: int, seed: int) -> list[tuple[NavigationCost, NavigationCost]]:
        n = len(self.scenarios)
        if not 2 <= k <= n:
            raise HybridnavError(f"kfold: expected 2 <= k <= {n} (the number of training "
                                 f"worlds), got {k}")
        f = fold_of(n, k, seed)
        out = []
        for j in range(k):
            tr = [s for s, g in zip(self.scenarios, f) if g != j]
            te = [s for s, g in zip(self.scenarios, f) if g == j]
            out.append((self.with_scenarios(tr, f"{self.name} without fold {j}"),
                        self.with_scenarios(te, f"fold {j}")))
        return out

    # ---- simulation ------------------------------------------------------------------------

    @property
    def packed(self):
        """The worlds packed for the lockstep simulation (built once per process)."""
        from hybridnav.tuner.evaluate import scenario_set

        return process_cache(f"navigation:{self.token}", lambda: scenario_set(self.scenarios))

    def __getstate__(self) -> dict[str, Any]:
        return dict(self.__dict__)

    def _noise(self, seed: int, keys: list[tuple[int, int]], repeats: int, steps: int):
        rw = self.reward
        sig = np.array([rw["heading_noise"], rw["dtheta_noise"], rw["alpha_noise"]])
        if not np.any(sig > 0):
            return None
        E = len(self.scenarios)
        out = np.empty((3, E, len(keys) * repeats, steps))
        for e in range(E):
            for k, (a, b) in enumerate(keys):
                for r in range(repeats):
                    ss = np.random.SeedSequence(seed, spawn_key=(a, b, e, r))
                    out[:, e, k * repeats + r] = (np.random.default_rng(ss).normal(
                        0.0, 1.0, (3, steps)) * sig[:, None])
        return out

    def simulate(self, family, tables, keys: list[tuple[int, int]] | None, *, seed: int = 0,
                 noise: bool = True, record_paths: bool = False):
        """Every system of ``tables`` on every world (``repeats`` times with noise).

        Returns
        -------
        (LockstepResult, repeats)
            Arrays of shape ``(worlds, K * repeats)``, member ``k * repeats + r``.
        """
        from hybridnav import planners

        st = self.packed
        K = tables.size
        repeats = self.reward["repeats"] if noise else 1
        dt = self.scenarios[0].dt
        steps = int(math.ceil(max(s.max_time for s in self.scenarios) / dt - 1e-9)) + 1
        keys = keys if keys is not None else [(VALIDATION_KEY, 0)] * K
        nz = self._noise(seed, keys, repeats, steps) if noise else None
        lockstep = planners.PLANNERS[self.planner].lockstep
        res = lockstep(st, family, tables, K * repeats, self.planner_params, repeats=repeats,
                       noise=nz, record_paths=record_paths)
        return res, repeats

    def run_costs(self, res, scenarios=None) -> np.ndarray:
        """The reward of every run, ``(worlds, members)``, by ``reward.kind`` (the paper's sign
        for ``paper``)."""
        from hybridnav.tuner.evaluate import run_costs

        return run_costs(self.reward, self.planner_params["speed"], scenarios or self.scenarios,
                         res)

    def assess(self, candidates: Candidates, context: Context) -> Evaluation:
        K = len(candidates)
        keys = None
        if context.role == "train":
            idx = context.indices if context.indices is not None else range(K)
            keys = [(context.generation, int(i)) for i in idx]
        res, repeats = self.simulate(candidates.family, candidates.tables, keys,
                                     seed=context.seed)
        E = len(self.scenarios)
        cost = self.run_costs(res).reshape(E, K, repeats).mean(axis=2)       # (E, K)
        kind = self.reward["kind"]
        total = cost.mean(axis=0) if kind == "deploy" else cost.sum(axis=0)
        cov = self.coverage
        unc = candidates.uncovered(cov["grid"])
        pen = cov["penalty"] * np.maximum(unc - cov["max_uncovered"], 0.0)
        fitness = total - pen if kind == "paper" else total + pen
        reached = (res.outcome == "reached").reshape(E, K, repeats)
        columns = []
        for o in self.objectives_measured:
            if o == "reward":
                columns.append(-fitness if kind == "paper" else fitness)
                continue
            if o == "failure":
                v = 1.0 - reached.mean(axis=(0, 2))
            elif o == "collision":
                crash = np.isin(res.outcome, ("collided", "out_of_bounds")).reshape(E, K, repeats)
                v = crash.mean(axis=(0, 2))
            elif o == "length":
                D = self._distances()[:, None, None]
                L = np.where(reached, res.path_length.reshape(E, K, repeats) / D, np.nan)
                n = reached.sum(axis=(0, 2))
                v = np.where(n > 0, np.nansum(L, axis=(0, 2)) / np.maximum(n, 1), np.inf)
            else:          # no obstacle in any world: the clearance counts as the diagonal
                diag = np.array([math.hypot(s.world.workspace[1] - s.world.workspace[0],
                                            s.world.workspace[3] - s.world.workspace[2])
                                 for s in self.scenarios])[:, None, None]
                c = np.minimum(res.min_clearance.reshape(E, K, repeats), diag)
                v = -c.min(axis=(0, 2))
            columns.append(v + pen)
        objective = np.column_stack(columns)
        details = []
        for k in range(K):
            envs = []
            for e, s in enumerate(self.scenarios):
                cols = slice(k * repeats, (k + 1) * repeats)
                envs.append({
                    "scenario": s.name,
                    "outcome": str(res.outcome[e, k * repeats]),
                    "reached": float(np.mean(reached[e, k])),
                    "length": float(np.mean(res.path_length[e, cols])),
                    "time": float(np.mean(res.time[e, cols])),
                    "clearance": float(np.min(res.min_clearance[e, cols])),
                    "reward": float(cost[e, k]),
                })
            details.append(envs)
        info = [{"fitness": float(f), "reward": float(t), "uncovered": float(u)}
                for f, t, u in zip(fitness, total, unc)]
        feasible = unc <= cov["max_uncovered"] + 1e-12
        return Evaluation(objective, feasible, info, details)

    def _distances(self) -> np.ndarray:
        """Per world the start-goal distance less the goal radius (at least the radius)."""
        r = [s.robots[0] for s in self.scenarios]
        d0 = np.array([math.dist(x.start, x.goal) for x in r])
        gr = np.array([x.goal_radius for x in r])
        return np.maximum(d0 - gr, gr)

    def evaluate(self, candidates: Candidates, context: Context) -> np.ndarray:
        return self.assess(candidates, context).objectives

    def fitness(self, objective: float) -> float:
        """An objective in the reward's own sense (the paper reward is maximized)."""
        return -objective if self.reward["kind"] == "paper" else objective

    # ---- judging ---------------------------------------------------------------------------

    def judge(self, systems: Mapping[str, Any], role: str = "test", *, backend=None,
              apf: bool = True) -> pd.DataFrame:
        """One row per (world, system): outcome, path length, time, minimum clearance — the
        systems simulated nominally (no noise) in one lockstep batch, plus the plain ``apf``
        planner with the same speed and turn limit."""
        from hybridnav.backends import SerialBackend
        from hybridnav.fuzzy.family import SystemFamily
        from hybridnav.tuner.heldout import (
            COLUMNS,
            _apf_rows,
            _lockstep_rows,
            baseline,
            planner_rows,
            uniform,
        )
        from hybridnav.world import scenario_to_dict

        labels = list(systems)
        rows = []
        if not uniform(self.scenarios):
            rows += planner_rows(role, self.scenarios, dict(systems), self.planner,
                                 self.planner_params)
            labels = []
        for label in labels:
            fam = SystemFamily(systems[label])
            res, _ = self.simulate(fam, fam.tables_of([systems[label]]), None, noise=False)
            rows += _lockstep_rows(role, self.scenarios, [label], res)
        if apf and labels:                 # one lockstep batch: what the planner does, run by run
            from hybridnav.planners.field.apf import apf_lockstep

            res = apf_lockstep(self.packed, baseline(dict(self.planner_params)))
            rows += _lockstep_rows(role, self.scenarios, ["apf"], res)
        elif apf:
            backend = backend or SerialBackend()
            args = [(json.dumps(scenario_to_dict(s)), dict(self.planner_params))
                    for s in self.scenarios]
            for s, runs in zip(self.scenarios, backend.map(_apf_rows, args)):
                rows += [{"set": role, "scenario": s.name, "system": "apf", **r} for r in runs]
        table = pd.DataFrame(rows, columns=COLUMNS)
        order = {n: i for i, n in enumerate(s.name for s in self.scenarios)}
        return table.sort_values(["scenario"], key=lambda c: c.map(order), kind="stable") \
            .reset_index(drop=True)

    def verdict(self, table: pd.DataFrame, role: str,
                falsified: pd.DataFrame | None = None) -> dict[str, Any]:
        """The deployment verdict of :func:`hybridnav.tuner.heldout.verdict` on ``role``'s rows
        (``falsified``: the falsification rates of start, tuned and apf, when searched)."""
        from hybridnav.tuner.heldout import summarize, verdict

        rows = table[table.set == role]
        return verdict(summarize(rows), role, self.robot_radius, falsified, rows)
