"""``tune(system, cost, ...)``: the one tuning loop, for every optimizer and every cost.

Each generation the optimizer is asked for vectors; they are evaluated in chunks on the backend
(the cost object and the settings travel to the workers as objects; each chunk's context carries
the generation and the candidates' indices, so results do not depend on chunking or workers); the
optimizer is told the objectives. Written once here for all optimizers:

**Validation and early stopping** (one objective). After every generation the ``top`` best
distinct candidates by training objective (in the first generation the start too) are scored on
the validation cost (scores cached per vector). The returned system is the best on
**validation** — never a candidate the cost calls infeasible over a feasible one — and the run
stops early when that score has not improved by more than ``tolerance`` for ``patience``
generations (0: never). Without validation the best on training is returned.

**k-fold** (``validation=KFold(k)`` or an int ``k >= 2``): the training cost is split into ``k``
folds (:meth:`Cost.folds`) and the optimizer runs ``k`` stages of its generations: stage ``j``
trains on the other folds, scores its best candidates on fold ``j`` (early stopping on that
score) and hands its population to stage ``j + 1`` (as MATLAB's ``tunefis`` with
``KFoldValue``). The returned system is the last stage's best on its own fold.

**Several objectives** (NSGA2): the Pareto front is the first non-dominated front of the final
population, one member per distinct system (the first in the population of the vectors that give
it); every member is scored on the validation cost and ``select`` (default
:func:`select_member`: the member with the smallest first validation objective among those the
cost calls feasible) picks the returned system.

**Checkpoints.** With ``checkpoint=DIR`` the state (optimizer state with its random generators,
validation trackers, logbook, position) is written atomically to ``DIR/checkpoint.json`` after
every generation, compactly; the per-candidate evaluation rows are appended to
``DIR/evaluations.jsonl`` (both written by a background thread while the workers compute the
next generation; the run waits for them before it returns). ``resume=True`` continues from them — refusing a checkpoint of another
configuration (``config_hash``) — and ends with exactly the result an uninterrupted run gives.
"""

from __future__ import annotations

import hashlib
import json
import logging
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from hybridnav import __version__
from hybridnav.backends import Backend, SerialBackend, Shipped
from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_write_text
from hybridnav.tuner.costs.base import Candidates, Context, Cost, Evaluation, evaluate_chunk
from hybridnav.tuner.optimizers import GA, Optimizer, Problem, non_dominated
from hybridnav.tuner.result import Member, TuningResult
from hybridnav.tuner.settings import TunableSettings

log = logging.getLogger(__name__)

__all__ = ["CHECKPOINT_FORMAT", "KFold", "learn", "select_member", "tune"]

CHECKPOINT_FORMAT = "hybridnav-tune-checkpoint/3"


@dataclass(frozen=True)
class KFold:
    """Cross-validation over the training cost's data in ``k`` folds; ``validation``
    (optional) a separate validation cost that picks the returned system."""

    k: int
    validation: Any = None

    def __post_init__(self) -> None:
        if not (isinstance(self.k, int) and not isinstance(self.k, bool) and self.k >= 2):
            raise HybridnavError(f"KFold: k: expected an integer >= 2, got {self.k!r}")


def select_member(front: pd.DataFrame) -> int:
    """The default rule for which front member is returned: among the members the cost calls
    feasible on validation (all, when none is), the smallest first validation objective (the
    first training objective without validation); ties go to the smaller second objective."""
    df = front
    col = "validation_0" if "validation_0" in df and df["validation_0"].notna().any() \
        else "objective_0"
    ok = df["validation_feasible"] if "validation_feasible" in df else \
        pd.Series(True, index=df.index)
    cand = df[ok] if ok.any() else df
    keys = [col] + [c for c in cand.columns if c.startswith(col.split("_")[0] + "_")
                    and c != col]
    return int(cand.sort_values(keys, kind="stable").index[0])


def _key(x: np.ndarray) -> bytes:
    return np.asarray(x, dtype=float).tobytes()


class _Track:
    """The best candidate on one validation cost, with its cache of scores."""

    def __init__(self) -> None:
        self.cache: dict[bytes, dict[str, Any]] = {}
        self.best: dict[str, Any] | None = None
        self.last_improvement = 0
        self.gen_best: float | None = None

    def dump(self) -> dict[str, Any]:
        return {"cache": list(self.cache.values()), "best": self.best,
                "last_improvement": self.last_improvement, "gen_best": self.gen_best}

    @classmethod
    def load(cls, d: dict[str, Any]) -> _Track:
        t = cls()
        t.cache = {_key(e["x"]): e for e in d["cache"]}
        t.best, t.last_improvement, t.gen_best = d["best"], d["last_improvement"], d["gen_best"]
        return t


class _Run:
    """The state of one tuning run and the steps of its loop."""

    def __init__(self, settings: TunableSettings, cost: Cost, optimizer: Optimizer,
                 validation: Cost | None, stages: list[tuple[Cost, Cost | None]], seed: int,
                 backend: Backend, chunk: int, top: int, patience: int, tolerance: float,
                 checkpoint: Path | None, progress: Callable | None) -> None:
        self.settings, self.cost, self.opt = settings, cost, optimizer
        self.validation, self.stages, self.seed = validation, stages, seed
        self.backend, self.chunk = backend, chunk
        self.top, self.patience, self.tolerance = top, patience, tolerance
        self.dir, self.progress = checkpoint, progress
        self.mo = cost.n_objectives > 1
        self.kfold = len(stages) > 1
        self.x0 = settings.to_vector()
        self.stage = 0
        self.logbook: list[dict[str, Any]] = []
        self.records: list[dict[str, Any]] = []
        self.start_objectives: list[float] | None = None
        self.elapsed = 0.0
        self.evaluations = 0
        self.val, self.fold = _Track(), _Track()
        self.stopped: int | None = None
        self.folds_done: list[dict[str, Any]] = []
        self.best_train: dict[str, Any] | None = None
        #: per generation, the best of the carried population (the logbook's min): stage,
        #: generation, score, x (what an animation of the run drives)
        self.generation_best: list[dict[str, Any]] = []
        self.max_evals = 0
        self.finished = False
        self._writer: ThreadPoolExecutor | None = None
        self._writes: list[Future] = []
        self._ship: dict[int, tuple[Any, Shipped]] = {}

    # ---- evaluation ------------------------------------------------------------------------

    def evaluate(self, cost: Cost, X: np.ndarray, context: Context) -> Evaluation:
        """``cost.assess`` of ``X`` in chunks on the backend.

        ``ceil(n / chunk)`` chunks of (nearly) equal size, dealt round robin: chunk ``k`` holds
        candidates ``k, k + m, k + 2m, ...`` of the ``m`` chunks. Both the sizes and the mix
        keep the workers' shares even: a GA generation asks for fewer than ``population``
        vectors (consecutive ranges gave 50 and 43), and its first generation draws the first
        half near the start (long drives) and the second at random (early crashes). The layout
        depends on ``n`` and ``chunk`` only, never on the workers; each candidate's context
        index is its place in ``X``.
        """
        n = len(X)
        if n == 0:
            return Evaluation(np.zeros((0, cost.n_objectives)))
        m = -(-n // self.chunk)
        parts = [np.arange(k, n, m) for k in range(m)]
        shipped = self._shipped(cost)
        args = [(shipped, self._shipped(self.settings), X[idx],
                 Context(context.seed, context.role, context.generation,
                         tuple(int(i) for i in idx)))
                for idx in parts]
        out = self.backend.map(evaluate_chunk, args)
        if m == 1:
            return out[0]
        order = np.argsort(np.concatenate(parts), kind="stable")
        ev = Evaluation.concat(out)
        return Evaluation(ev.objectives[order], ev.feasible[order],
                          [ev.info[i] for i in order], [ev.details[i] for i in order])

    def _shipped(self, obj: Any) -> Shipped:
        """``obj`` wrapped once per run: the workers unpickle each cost and the settings once
        (with what they build from them: packed worlds, the fuzzy family), not per chunk."""
        entry = self._ship.get(id(obj))
        if entry is None or entry[0] is not obj:
            entry = self._ship[id(obj)] = (obj, Shipped(obj))
        return entry[1]

    # ---- validation ------------------------------------------------------------------------

    def candidates(self, X: np.ndarray, F: np.ndarray, first: bool) -> list[np.ndarray]:
        order = np.argsort(F[:, 0], kind="stable")
        out, seen = [], set()
        for i in order:
            k = _key(X[i])
            if k not in seen:
                seen.add(k)
                out.append(X[i])
            if len(out) == self.top:
                break
        if first and _key(self.x0) not in seen:
            out.append(self.x0)
        return out

    def score(self, cost: Cost, role: str, cands: list[np.ndarray], train: dict[bytes, float],
              generation: int, track: _Track) -> None:
        todo = list({_key(x): x for x in cands if _key(x) not in track.cache}.values())
        if todo:
            ev = self.evaluate(cost, np.array(todo), Context(self.seed, role, generation))
            for x, f, ok, info, det in zip(todo, ev.objectives, ev.feasible, ev.info,
                                           ev.details):
                track.cache[_key(x)] = {
                    "x": np.asarray(x, dtype=float).tolist(), "score": float(f[0]),
                    "objectives": f.tolist(), "feasible": bool(ok), "info": info,
                    "train": train.get(_key(x)), "stage": self.stage, "generation": generation,
                    "details": det}
        scores = [track.cache[_key(x)]["score"] for x in cands]
        track.gen_best = float(min(scores))
        for x in cands:
            entry = track.cache[_key(x)]
            ok = entry["feasible"]
            best_ok = track.best is not None and track.best["feasible"]
            if ok != best_ok and track.best is not None:        # feasibility first
                if not ok:
                    continue
                track.best = dict(entry, stage=self.stage, generation=generation)
                track.last_improvement = generation
                continue
            if track.best is None or entry["score"] < track.best["score"]:
                improved = (track.best is None
                            or abs(entry["score"] - track.best["score"]) > self.tolerance)
                track.best = dict(entry, stage=self.stage, generation=generation)
                if improved:
                    track.last_improvement = generation

    def after_generation(self, gen: int, X: np.ndarray, F: np.ndarray, ev_X: np.ndarray,
                         ev: Evaluation) -> None:
        if self.mo:                       # several objectives: the front is scored at the end
            return
        train = {_key(x): float(f[0]) for x, f in zip(X, F)}
        train.update({_key(x): float(f[0]) for x, f in zip(ev_X, ev.objectives)})
        cands = self.candidates(X, F, gen == 0)        # the start competes in every stage
        fold_cost = self.stages[self.stage][1]
        if fold_cost is not None:
            self.score(fold_cost, "fold", cands, train, gen, self.fold)
        if self.validation is not None:
            self.score(self.validation, "validation", cands, train, gen, self.val)
        watch = self.fold if fold_cost is not None else (self.val if self.validation else None)
        if watch is not None and self.patience and \
                gen - watch.last_improvement >= self.patience and gen < self.opt.generations:
            self.stopped = gen
            log.info("early stop in stage %d at generation %d: no improvement since %d",
                     self.stage, gen, watch.last_improvement)

    # ---- one generation --------------------------------------------------------------------

    def step(self) -> None:
        tic = time.perf_counter()
        gen = self.opt.generation
        key = self.stage * (self.opt.generations + 1) + gen      # distinct noise per stage
        X = self.opt.ask()
        train_cost = self.stages[self.stage][0]
        ev = self.evaluate(train_cost, X, Context(self.seed, "train", key))
        self.opt.tell(X, ev.objectives)
        self.evaluations += len(X)
        if self.start_objectives is None:
            at = [i for i, x in enumerate(X) if _key(x) == _key(self.x0)]
            if at:
                self.start_objectives = ev.objectives[at[0]].tolist()
            else:
                e0 = self.evaluate(train_cost, self.x0[None], Context(self.seed, "train", key))
                self.start_objectives = e0.objectives[0].tolist()
        rows = self._rows(X, ev, gen)
        self.records += rows
        for x, f, ok in zip(X, ev.objectives, ev.feasible):
            better = self.best_train is None or (
                (bool(ok), -f[0]) > (self.best_train["feasible"], -self.best_train["score"]))
            if better:
                self.best_train = {"x": x.tolist(), "score": float(f[0]), "feasible": bool(ok),
                                   "stage": self.stage, "generation": gen}
        PX, PF = self.opt.population()
        if len(PF):
            b = int(np.argmin(PF[:, 0]))
            self.generation_best.append({"stage": self.stage, "generation": gen,
                                         "score": float(PF[b, 0]),
                                         "x": np.asarray(PX[b], dtype=float).tolist()})
        self.after_generation(gen, PX, PF, X, ev)
        self.elapsed += time.perf_counter() - tic
        row = self._logrow(gen, len(X), PF)
        self.logbook.append(row)
        self.save(rows)
        if self.progress:
            self.progress(row)

    def _rows(self, X: np.ndarray, ev: Evaluation, gen: int) -> list[dict[str, Any]]:
        rows = []
        base = {"stage": self.stage, "generation": gen,
                "set": getattr(self.stages[self.stage][0], "name", "train")}
        for i, (f, info, det) in enumerate(zip(ev.objectives, ev.info, ev.details)):
            head = {**base, "individual": i}
            objs = {f"objective_{j}": float(v) for j, v in enumerate(f)}
            if det:
                rows += [{**d, **head, **info} for d in det]
            else:
                rows.append({**head, **objs, **info})
        return rows

    def _logrow(self, gen: int, nevals: int, F: np.ndarray) -> dict[str, Any]:
        row: dict[str, Any] = {}
        if self.kfold:
            row["stage"] = self.stage
        row["gen"] = gen
        row["evals"] = nevals
        f = F[:, 0] if len(F) else np.array([np.nan])
        fin = f[np.isfinite(f)]
        row.update({"min": float(f.min()), "mean": float(fin.mean()) if len(fin) else np.inf,
                    "max": float(f.max()), "std": float(fin.std()) if len(fin) else np.nan})
        if self.mo:
            for j in range(1, F.shape[1]):
                row[f"min_{j}"] = float(F[:, j].min())
            row["front"] = int(non_dominated(F).sum())
        if self.validation is not None and not self.mo:
            row["val_gen"] = self.val.gen_best
            row["val_best"] = self.val.best["score"] if self.val.best else None
        if self.kfold:
            row["fold_gen"] = self.fold.gen_best
            row["fold_best"] = self.fold.best["score"] if self.fold.best else None
        row["wall_time"] = self.elapsed
        return row

    # ---- loop ------------------------------------------------------------------------------

    def run(self, stop_after: int | None) -> None:
        done = len(self.logbook)
        if self.finished:                     # a finished run resumed: nothing left to do
            return
        while self.stage < len(self.stages):
            while not self.opt.done and self.stopped is None and not (
                    self.max_evals and self.evaluations >= self.max_evals):
                if stop_after is not None and done > stop_after:
                    return
                self.step()
                done += 1
            if self.kfold and self.fold.best is not None:
                self.folds_done.append({"stage": self.stage, "fold": self.stage,
                                        "stopped": self.stopped, **self.fold.best})
            self.fold = _Track()
            spent = bool(self.max_evals and self.evaluations >= self.max_evals)
            if self.stage + 1 < len(self.stages) and not spent:
                self.stage += 1
                self.stopped = None
                self.opt.new_stage()
                self.save([])
            else:
                self.save([], finished=True)
                self.finished = True
                return

    # ---- checkpoints -----------------------------------------------------------------------

    def state(self, finished: bool) -> dict[str, Any]:
        return {"stage": self.stage, "finished": finished, "optimizer": self.opt.state(),
                "logbook": self.logbook, "start_objectives": self.start_objectives,
                "elapsed": self.elapsed, "evaluations": self.evaluations,
                "validation": self.val.dump(), "fold": self.fold.dump(),
                "stopped": self.stopped, "folds_done": self.folds_done,
                "best_train": self.best_train, "generation_best": self.generation_best}

    def save(self, rows: list[dict[str, Any]], finished: bool = False) -> None:
        """Append a generation's rows to ``evaluations.jsonl`` and write the checkpoint.

        The state is serialized here; the rows (about 3,000 per generation of the main job,
        which take longer to serialize than the state) and both files are written by one
        background thread, in order, while the workers compute the next generation.
        :meth:`flush` waits for them (the end of :meth:`run`); a write that failed raises at
        the next save or flush. A process killed meanwhile leaves the previous checkpoint and
        perhaps the rows of a generation after it, which a resume drops and computes again.
        """
        if self.dir is None:
            return
        state = {"format": CHECKPOINT_FORMAT, "version": __version__,
                 "config_hash": self.config_hash, **self.state(finished)}
        text = json.dumps(state)
        for fut in [f for f in self._writes if f.done()]:
            self._writes.remove(fut)
            fut.result()                              # a failed write raises here
        if self._writer is None:
            self._writer = ThreadPoolExecutor(1, thread_name_prefix="hybridnav-checkpoint")
        self._writes.append(self._writer.submit(self._write, self.dir, rows, text))

    @staticmethod
    def _write(folder: Path, rows: list[dict[str, Any]], state_text: str) -> None:
        if rows:
            with open(folder / "evaluations.jsonl", "a", encoding="utf-8") as fh:
                fh.write("".join(json.dumps(r) + "\n" for r in rows))
        atomic_write_text(folder / "checkpoint.json", state_text)

    def flush(self) -> None:
        """Wait for the checkpoint writes under way (raising the first that failed)."""
        writes, self._writes = self._writes, []
        try:
            for fut in writes:
                fut.result()
        finally:
            if self._writer is not None:
                self._writer.shutdown(wait=True)
                self._writer = None

    def restore(self, state: dict[str, Any]) -> None:
        path = self.dir / "checkpoint.json"
        try:
            self._restore(state)
        except HybridnavError as exc:
            raise HybridnavError(f"{path}: {exc}") from None
        except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
            raise HybridnavError(f"{path}: damaged checkpoint ({type(exc).__name__}: {exc}); "
                                 "start again without --resume") from None
        X = self.opt.population()[0]
        if X.ndim != 2 or X.shape[1] != self.settings.size:
            raise HybridnavError(f"{path}: damaged checkpoint (population of shape {X.shape}, "
                                 f"expected vectors of {self.settings.size})")

    def _restore(self, state: dict[str, Any]) -> None:
        self.stage = int(state["stage"])
        self.opt.set_state(state["optimizer"])
        self.logbook = state["logbook"]
        self.start_objectives = state["start_objectives"]
        self.elapsed, self.evaluations = state["elapsed"], state["evaluations"]
        self.val, self.fold = _Track.load(state["validation"]), _Track.load(state["fold"])
        self.stopped, self.folds_done = state["stopped"], state["folds_done"]
        self.best_train = state["best_train"]
        # (checkpoints of hybridnav before 0.3.0 have none: the generations before go unseen)
        self.generation_best = list(state.get("generation_best", []))
        self.finished = bool(state["finished"])
        pos = (self.stage, self.opt.generation)
        self.records = [r for r in _read_jsonl(self.dir / "evaluations.jsonl")
                        if (r["stage"], r["generation"]) < pos]
        # the rows of a generation after the checkpoint were never part of this run
        atomic_write_text(self.dir / "evaluations.jsonl",
                          "".join(json.dumps(r) + "\n" for r in self.records))


def _read_jsonl(path: Path) -> list[dict[str, Any]]:
    """The evaluation rows of a checkpointed run; a last line cut by a kill is dropped (its
    generation is redone), any other damage is an error naming the file and line."""
    out: list[dict[str, Any]] = []
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        return out
    except (OSError, UnicodeDecodeError) as exc:
        raise HybridnavError(f"{path}: unreadable ({exc})") from None
    for i, line in enumerate(lines):
        try:
            row = json.loads(line)
        except (json.JSONDecodeError, RecursionError):
            if i == len(lines) - 1:             # cut by a kill
                break
            raise HybridnavError(f"{path}: line {i + 1}: expected a JSON row") from None
        if not (isinstance(row, dict) and isinstance(row.get("stage"), int)
                and isinstance(row.get("generation"), int)):
            raise HybridnavError(f"{path}: line {i + 1}: expected a row with an integer stage "
                                 "and generation")
        out.append(row)
    return out


def _load_checkpoint(path: Path, chash: str) -> dict[str, Any]:
    try:
        state = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise HybridnavError(f"{path}: no checkpoint to resume from (run without --resume "
                             "first)") from None
    except (OSError, json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
        raise HybridnavError(f"{path}: unreadable checkpoint ({exc})") from None
    if not isinstance(state, dict) or state.get("format") != CHECKPOINT_FORMAT:
        raise HybridnavError(f"{path}: format: expected {CHECKPOINT_FORMAT!r}, got "
                             f"{state.get('format') if isinstance(state, dict) else state!r}")
    if state.get("config_hash") != chash:
        raise HybridnavError(
            f"{path}: config_hash: this checkpoint was written by a different configuration "
            f"(checkpoint {str(state.get('config_hash'))[:12]}, this run {chash[:12]}); resume "
            "with the same job and seed, or start a new run in another folder")
    return state


def _check_picklable(cost: Cost, validation: Cost | None, backend) -> None:
    """Local worker processes receive the costs pickled: say so before any work."""
    from hybridnav.backends import ProcessBackend

    if not isinstance(backend, ProcessBackend):
        return
    import pickle

    for c in (cost, validation):
        if c is None:
            continue
        try:
            pickle.dumps(c)
        except (pickle.PicklingError, AttributeError, TypeError) as exc:
            raise HybridnavError(
                f"cost: {type(c).__name__} cannot be sent to worker processes ({exc}); use a "
                "function defined at module level, or FunctionCost('module:function')") \
                from None


def _config_hash(parts: dict[str, Any]) -> str:
    text = json.dumps(parts, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def tune(system, cost: Cost, *, settings: TunableSettings | None = None,
         optimizer: Optimizer | None = None, validation: Cost | float | int | KFold | None = None,
         test: Cost | None = None, seed: int = 0, backend: Backend | None = None,
         checkpoint: str | Path | None = None, progress: Callable | None = None,
         resume: bool = False, chunk: int = 50, top: int = 3, patience: int | None = None,
         tolerance: float = 0.0, select: Callable[[pd.DataFrame], int] | None = None,
         name: str | None = None, judge: bool = True, max_evals: int = 0,
         stop_after: int | None = None, phase: Callable[[str], None] | None = None
         ) -> TuningResult:
    """Tune ``system`` to minimize ``cost``.

    Parameters
    ----------
    system : FuzzySystem
        The starting system (its structure is kept).
    cost : Cost
        :class:`NavigationCost`, :class:`DataCost`, :class:`FunctionCost` or your own.
    settings : TunableSettings, optional
        What is free (default: every membership-function parameter of ``system``).
    optimizer : Optimizer, optional
        :class:`GA` (default), :class:`CMAES`, :class:`PSO` or :class:`NSGA2` (several
        objectives; the default when the cost has several).
    validation : Cost, float, int or KFold, optional
        A validation cost (the returned system is the best on it), a fraction of the cost's
        data held out for validation (``cost.split``), or ``k``/``KFold(k)`` for k-fold
        cross-validation (``cost.folds``).
    test : Cost, optional
        Data only reported: start and tuned are judged on it (and on validation) after tuning.
    seed : int
        All randomness (optimizer, noise streams, splits) derives from it.
    backend : Backend, optional
        Where chunks of a generation are evaluated (default: this process); see
        :func:`hybridnav.backends.make_backend`.
    checkpoint : path, optional
        Folder for ``checkpoint.json`` and ``evaluations.jsonl`` (created).
    progress : callable, optional
        ``progress(row)`` after every generation with its logbook row.
    phase : callable, optional
        ``phase(message)`` when a phase after the optimizer starts (judging start and tuned on
        the validation and test sets), for a progress display.
    resume : bool
        Continue from ``checkpoint``.
    chunk : int
        At most this many candidates per unit of parallel work: ``ceil(n / chunk)`` chunks of
        nearly equal size, dealt round robin (the layout depends on ``n`` and ``chunk`` only).
        Part of the configuration: the batched arithmetic of a chunk can round differently
        (1e-14) from that of another size, so a run is reproduced exactly — on any backend and
        number of workers — with the same chunk.
    top, patience, tolerance :
        Validation: candidates scored per generation, generations without improvement before
        stopping (0: never; None: the optimizer's ``default_patience``: GA 10, PSO 15, CMA-ES
        and NSGA-II 0), and the improvement that counts.
    select : callable, optional
        Several objectives: ``select(front) -> index`` of the returned member (default
        :func:`select_member`).
    name : str, optional
        The tuned system's name (default ``<start>-tuned``).
    judge : bool
        Judge start and tuned on the validation and test costs after tuning.
    max_evals : int
        Stop once this many candidates have been evaluated on training (0: the optimizer's own
        budget only); the generation under way finishes.
    stop_after : int, optional
        Stop after this many generations (tests of interruption; the checkpoint stays).

    Returns
    -------
    TuningResult

    Examples
    --------
    >>> from hybridnav.tuner import tune, DataCost, CMAES           # doctest: +SKIP
    >>> result = tune(start, DataCost(X, y), optimizer=CMAES(), seed=3)
    >>> result.system.save("tuned.json")
    """
    from hybridnav.fuzzy import FuzzySystem

    if not isinstance(system, FuzzySystem):
        raise HybridnavError(f"system: expected a FuzzySystem, got {type(system).__name__}")
    if not isinstance(cost, Cost):
        raise HybridnavError(f"cost: expected a Cost (NavigationCost, DataCost, FunctionCost or "
                             f"a subclass of hybridnav.tuner.Cost), got {type(cost).__name__}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise HybridnavError(f"seed: expected a non-negative integer, got {seed!r}")
    seed = int(seed)
    settings = settings if settings is not None else TunableSettings(system)
    if not isinstance(settings, TunableSettings):
        raise HybridnavError(f"settings: expected TunableSettings, got {type(settings).__name__}")
    if settings.template != system:
        raise HybridnavError("settings: built from another system than the one tuned; build "
                             "them with TunableSettings(system)")
    if settings.size == 0:
        raise HybridnavError("settings: nothing is free (free a variable, term or rule setting)")
    if optimizer is None:
        from hybridnav.tuner.optimizers import NSGA2

        optimizer = NSGA2() if cost.n_objectives > 1 else GA()
    if not isinstance(optimizer, Optimizer):
        raise HybridnavError(f"optimizer: expected GA, CMAES, PSO or NSGA2, got "
                             f"{type(optimizer).__name__}")
    cost.check(settings)
    stages: list[tuple[Cost, Cost | None]] = [(cost, None)]
    val_cost: Cost | None = None
    if isinstance(validation, int) and not isinstance(validation, bool):
        validation = KFold(validation)
    if isinstance(validation, KFold):
        stages = [(a, b) for a, b in cost.folds(validation.k, seed)]
        val_cost = validation.validation
    elif isinstance(validation, float):
        cost, val_cost = cost.split(validation, seed)
        stages = [(cost, None)]
    elif isinstance(validation, Cost):
        val_cost = validation
    elif validation is not None:
        raise HybridnavError(f"validation: expected a Cost, a fraction, k or KFold(k), got "
                             f"{validation!r}")
    for what, c in (("validation", val_cost), ("test", test)):
        if c is not None:
            if not isinstance(c, Cost):
                raise HybridnavError(f"{what}: expected a Cost, got {type(c).__name__}")
            c.check(settings)
    if patience is None:
        patience = optimizer.default_patience
    for k, v, lo in (("chunk", chunk, 1), ("top", top, 1), ("patience", patience, 0),
                     ("max_evals", max_evals, 0)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
            raise HybridnavError(f"{k}: expected an integer >= {lo}, got {v!r}")
    if stop_after is not None and (isinstance(stop_after, bool)
                                   or not isinstance(stop_after, int) or stop_after < 0):
        raise HybridnavError(f"stop_after: expected an integer >= 0, got {stop_after!r}")
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float)) or \
            not np.isfinite(tolerance) or tolerance < 0:
        raise HybridnavError(f"tolerance: expected a non-negative number, got {tolerance!r}")
    if backend is not None and not isinstance(backend, Backend):
        raise HybridnavError(f"backend: expected a Backend (hybridnav.backends.make_backend), "
                             f"got {backend!r}")
    if progress is not None and not callable(progress):
        raise HybridnavError(f"progress: expected a callable, got {progress!r}")
    if phase is not None and not callable(phase):
        raise HybridnavError(f"phase: expected a callable, got {phase!r}")
    if select is not None and not callable(select):
        raise HybridnavError(f"select: expected a callable, got {select!r}")
    if checkpoint is not None and not isinstance(checkpoint, (str, Path)):
        raise HybridnavError(f"checkpoint: expected a folder path, got {checkpoint!r}")
    _check_picklable(cost, val_cost, backend)
    problem = Problem(settings.lower, settings.upper, settings.to_vector(), settings.repair,
                      cost.n_objectives)
    optimizer.setup(problem, seed)
    run = _Run(settings, cost, optimizer, val_cost, stages, seed, backend or SerialBackend(),
               chunk, top, patience, float(tolerance), None, progress)
    run.max_evals = max_evals
    run.config_hash = _config_hash({
        "settings": settings.key(), "cost": cost.config(),
        "validation": val_cost.config() if val_cost else None,
        "kfold": len(stages) if len(stages) > 1 else 0, "optimizer": optimizer.config(),
        "seed": seed, "top": top, "patience": patience, "tolerance": tolerance,
        "max_evals": max_evals, "chunk": chunk, "chunking": "round-robin"})
    if checkpoint is not None:
        run.dir = Path(checkpoint)
        try:
            run.dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise HybridnavError(f"checkpoint: {checkpoint}: cannot make the folder ({exc})") \
                from None
        if resume:
            run.restore(_load_checkpoint(run.dir / "checkpoint.json", run.config_hash))
            log.info("resuming at stage %d, generation %d", run.stage, optimizer.generation)
        else:
            (run.dir / "evaluations.jsonl").unlink(missing_ok=True)
    elif resume:
        raise HybridnavError("resume: expected a checkpoint folder to resume from")
    try:
        run.run(stop_after)
    finally:
        run.flush()
    return _result(run, system, settings, select, name, judge, test, backend, phase)


def _result(run: _Run, start, settings: TunableSettings, select, name, judge: bool,
            test: Cost | None, backend, phase=None) -> TuningResult:
    opt = run.opt
    cost = run.cost
    X, F = opt.population()
    members: list[Member] = []
    selected_by = "training"
    stage = run.stage
    front = pd.DataFrame()
    if run.mo:
        nd = non_dominated(F)
        fX, fF = X[nd], F[nd]
        # one member per distinct system: vectors that differ only in genes the system does not
        # use (a switched-off rule's terms) are one member, the first in the population
        keys = [json.dumps(settings.to_system(x).to_dict(), sort_keys=True) for x in fX]
        uniq = np.array(sorted({k: i for i, k in reversed(list(enumerate(keys)))}.values()),
                        dtype=int)
        fX, fF = fX[uniq], fF[uniq]
        front = pd.DataFrame(fF, columns=[f"objective_{i}" for i in range(fF.shape[1])])
        if run.validation is not None:
            ev = run.evaluate(run.validation, fX, Context(run.seed, "validation", 0))
            for i in range(ev.objectives.shape[1]):
                front[f"validation_{i}"] = ev.objectives[:, i]
            front["validation_feasible"] = ev.feasible
            selected_by = "validation"
        pick = (select or select_member)(front.copy())
        if isinstance(pick, bool) or not isinstance(pick, (int, np.integer)) or \
                not 0 <= pick < len(front):
            raise HybridnavError(f"select: expected the index of a front member in [0, "
                                 f"{len(front) - 1}], got {pick!r}")
        pick = int(pick)
        chosen_x, best_gen = fX[pick], opt.generation - 1
        for i, (x, f) in enumerate(zip(fX, fF)):
            members.append(Member(settings.to_system(x, name=f"{start.name}-front-{i}"),
                                  f, x, front.iloc[i].to_dict()))
        front.insert(0, "member", range(len(front)))
        front["returned"] = front.index == pick
        chosen_F = fF[pick]
    else:
        if run.validation is not None and run.val.best is not None:
            chosen, selected_by = run.val.best, "validation"
        elif run.kfold and run.folds_done and "x" in run.folds_done[-1]:
            chosen, selected_by = run.folds_done[-1], f"fold {run.folds_done[-1]['fold']}"
        else:
            chosen = run.best_train
        chosen_x = np.array(chosen["x"], dtype=float)
        best_gen, stage = chosen["generation"], chosen.get("stage", stage)
        t = chosen.get("train", chosen["score"])
        if t is None:          # the start, chosen on a fold of a stage it was not trained in
            t = run.start_objectives[0] if _key(chosen_x) == _key(run.x0) else np.nan
        chosen_F = np.array([t], dtype=float)
        front = pd.DataFrame({"member": [0], "objective_0": chosen_F})
        members = [Member(None, chosen_F, chosen_x, {})]
    tuned_name = name or f"{start.name}-tuned"
    description = (f"Tuned by hybridnav {__version__} from {start.name!r} ({cost.describe()}; "
                   f"optimizer {opt.name}, seed {run.seed}): generation {best_gen}"
                   + (f" of stage {stage}" if run.kfold else "")
                   + f", chosen by its {selected_by} score.")
    system = settings.to_system(chosen_x, name=tuned_name, description=description)
    if not run.mo:
        members[0].system = system
    validation = pd.DataFrame([
        {k: v for k, v in c.items() if k not in ("x", "details", "info", "objectives")}
        | c.get("info", {}) for c in run.val.cache.values()])
    vdetails = pd.DataFrame([dict(d, generation=c["generation"], score=c["score"])
                             for c in run.val.cache.values() for d in c["details"]])
    start_val = run.val.cache.get(_key(run.x0))
    made: dict[bytes, Any] = {}            # one system per distinct vector
    generations = []
    for g in run.generation_best:
        k = _key(g["x"])
        if k not in made:
            made[k] = settings.to_system(np.asarray(g["x"], dtype=float),
                                         name=f"{tuned_name}-generation-{g['generation']}")
        generations.append({"stage": g["stage"], "generation": g["generation"],
                            "score": g["score"], "system": made[k]})
    result = TuningResult(
        system=system, start=start, settings=settings, x=chosen_x, x_start=run.x0,
        objectives=np.asarray(chosen_F, dtype=float),
        start_objectives=np.asarray(run.start_objectives, dtype=float),
        objective_names=tuple(cost.objective_names), front=front, members=members,
        logbook=pd.DataFrame(run.logbook), validation=validation,
        validation_details=vdetails, records=pd.DataFrame(run.records),
        selected_by=selected_by, best_generation=int(best_gen), best_stage=int(stage),
        stopped=run.stopped if not run.kfold else None, folds=run.folds_done,
        validation_score=(run.val.best or {}).get("score"),
        start_validation_score=start_val["score"] if start_val else None,
        optimizer=opt.config(), cost=cost.describe(), seed=run.seed,
        wall_time=run.elapsed, evaluations=run.evaluations, config_hash=run.config_hash,
        finished=run.finished, patience=run.patience, generations=generations)
    result.validation_cost = run.validation
    if settings.to_system(run.x0) != start:   # the repair changed it (e.g. min_overlap)
        score_start(result, start, run.stages[0][0], run.validation, run.seed, run)
    if judge:
        _judge(result, start, run.validation, test, backend, phase)
    return result


def score_start(result: TuningResult, start, cost: Cost, validation: Cost | None, seed: int,
                run: _Run | None = None) -> None:
    """Score the system the user started from itself (not its repaired vector, not a learned
    rule base): ``result.start_objectives`` on the training cost (nominal context of generation
    0) and ``result.start_validation_score``; ``result.start_is_candidate`` says whether the
    search could return it."""
    one = Candidates.of(start)
    ctx = Context(seed, "train", 0, (0,))
    result.start_objectives = evaluate_chunk(cost, one.settings, one.X, ctx).objectives[0]
    if validation is not None:
        ev = evaluate_chunk(validation, one.settings, one.X, Context(seed, "validation"))
        result.start_validation_score = float(ev.objectives[0, 0])
    result.start_is_candidate = False


def _judge(result: TuningResult, start, validation: Cost | None, test: Cost | None,
           backend, phase: Callable[[str], None] | None = None) -> None:
    """Start and tuned on the validation and test costs: ``result.heldout`` and verdicts."""
    systems = {"start": start, "tuned": result.system}
    roles = [(role, c) for role, c in (("validation", validation), ("test", test))
             if c is not None]
    if roles and phase is not None:
        phase("judging start and tuned on the " + " and ".join(role for role, _ in roles)
              + " data")
    if len(roles) > 1 and backend is not None and not isinstance(backend, SerialBackend):
        # the held-out sets are independent: one worker each (a worker judges its set alone)
        judged = backend.map(_judge_one, [(c, systems, role) for role, c in roles])
    else:
        judged = [c.judge(systems, role, backend=backend) for role, c in roles]
    tables = []
    for (role, c), t in zip(roles, judged):
        tables.append(t)
        v = c.verdict(t, role)
        if role == "validation" and v.get("headline"):
            v["headline"] += (" — on the data that chose the returned system, not an "
                              "independent test" + ("" if test is not None else
                                                    "; give a test set for one"))
        result.verdicts[role] = v
    if tables:
        result.heldout = pd.concat(tables, ignore_index=True)


def _judge_one(cost: Cost, systems: dict[str, Any], role: str) -> pd.DataFrame:
    """``cost.judge`` of ``systems`` on ``role``'s data (one unit of work of :func:`_judge`)."""
    return cost.judge(systems, role)


def first_train_cost(cost: Cost, fraction: float, seed: int) -> Cost:
    """The training part of a cost split by ``tune(validation=fraction)``."""
    return cost.split(fraction, seed)[0]


def learn(system, cost: Cost, *, max_rules: int = 10, keep_rules: bool = True,
          rule_weights: bool = False, rule_optimizer: Optimizer | None = None,
          optimizer: Optimizer | None = None, settings: Callable | None = None,
          checkpoint: str | Path | None = None, resume: bool = False, test: Cost | None = None,
          backend: Backend | None = None, name: str | None = None, judge: bool = True,
          **kw: Any) -> TuningResult:
    """Learn a rule base, then tune the learned system's membership functions (MATLAB's
    two-stage ``OptimizationType = "learning"`` then ``"tuning"``).

    Stage 1 tunes :meth:`TunableSettings.learning` settings (up to ``max_rules`` rules, each
    per input a term, NOT a term or "don't care", a consequent and optionally a weight; MFs
    fixed) with ``rule_optimizer``; stage 2 tunes the MFs of the learned rule base
    (``settings(learned)``, default ``TunableSettings(learned)``) with ``optimizer``. Both stages
    share ``validation``, ``seed`` and the other :func:`tune` arguments (``**kw``); their
    checkpoints are ``checkpoint/learning`` and ``checkpoint``. The result is stage 2's, judged
    against the *original* start; ``result.learning`` is stage 1's.

    Parameters
    ----------
    system : FuzzySystem
        The variables and terms to use; its rules start the rule base unless ``keep_rules`` is
        False (an empty rule base).
    cost : Cost
    max_rules : int
    keep_rules : bool
    rule_weights : bool
        Learn rule weights too.
    rule_optimizer, optimizer : Optimizer, optional
        The two stages' optimizers (default: :class:`GA` each).
    settings : callable, optional
        ``settings(learned) -> TunableSettings`` for stage 2.
    checkpoint, resume, test, backend, name, judge :
        As :func:`tune`.
    **kw
        Further :func:`tune` arguments (``validation``, ``seed``, ``chunk``, ``patience``, ...).
    """
    if settings is not None and not callable(settings):
        raise HybridnavError("settings: expected a callable settings(learned) -> "
                             "TunableSettings (the learned system is known only after stage 1)")
    for k, v in (("keep_rules", keep_rules), ("rule_weights", rule_weights)):
        if not isinstance(v, bool):
            raise HybridnavError(f"{k}: expected true or false, got {v!r}")
    ck = None if checkpoint is None else Path(checkpoint)
    s1 = TunableSettings.learning(system, max_rules, keep_rules=keep_rules,
                                  rule_weights=rule_weights)
    first = tune(s1.template, cost, settings=s1, optimizer=rule_optimizer or GA(),
                 checkpoint=None if ck is None else ck / "learning", resume=resume,
                 backend=backend, judge=False, name=f"{system.name}-learned", **kw)
    if not first.finished:                      # interrupted (stop_after): stage 1 only
        return first
    learned = first.system
    s2 = settings(learned) if settings is not None else TunableSettings(learned)
    second = tune(learned, cost, settings=s2, optimizer=optimizer or GA(), checkpoint=ck,
                  resume=resume and ck is not None and (ck / "checkpoint.json").exists(),
                  backend=backend, judge=False, name=name or f"{system.name}-tuned", **kw)
    if not second.finished:
        return second
    second.start, second.learning = system, first
    score_start(second, system, cost if not isinstance(kw.get("validation"), float)
                else first_train_cost(cost, kw["validation"], kw.get("seed", 0)),
                second.validation_cost, kw.get("seed", 0))
    if judge:
        _judge(second, system, second.validation_cost, test, backend, kw.get("phase"))
    return second

