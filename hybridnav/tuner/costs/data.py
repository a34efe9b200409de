"""Tuning to input/output samples: :class:`DataCost` (what MATLAB's ``tunefis(fis, paramset, in,
out)`` does).

The objective is the RMSE (or MAE) between the system's output and the samples' outputs, every
candidate of a batch evaluated on every sample in one batched call.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from hybridnav.errors import HybridnavError
from hybridnav.tuner.costs.base import Candidates, Context, Cost, Evaluation, fold_of, permutation

__all__ = ["METRICS", "DataCost"]

METRICS = ("rmse", "mae")


class DataCost(Cost):
    """The error of a system against input/output samples.

    Parameters
    ----------
    inputs : array_like (n, k) or pandas.DataFrame
        An ``(n, k)`` array whose columns are the system's inputs in its input order, or a
        DataFrame whose columns are named as the system's inputs (any order; other columns are
        ignored).
    outputs : array_like (n,) or pandas.Series
        The desired outputs.
    metric : {"rmse", "mae"}
        Root mean square or mean absolute error.
    source : str, optional
        Where the samples came from (named in messages).

    Examples
    --------
    >>> import numpy as np
    >>> from hybridnav import fuzzy
    >>> from hybridnav.tuner import DataCost, tune, CMAES
    >>> fis = fuzzy.builtin("effc-2rule")
    >>> X = np.random.default_rng(0).uniform([0, 0], [1.5, 2], (200, 2))
    >>> cost = DataCost(X, fis.evaluate(dtheta=X[:, 0], alpha=X[:, 1]))
    """

    def __init__(self, inputs: Any, outputs: Any, *, metric: str = "rmse",
                 source: str | None = None) -> None:
        super().__init__()
        where = f"{source}: " if source else ""
        if metric not in METRICS:
            raise HybridnavError(f"{where}metric: expected one of {', '.join(METRICS)}, got "
                                 f"{metric!r}")
        self.metric = metric
        self.source = source
        self.objective_names = (metric,)
        if isinstance(inputs, pd.DataFrame):
            names = [str(c) for c in inputs.columns]
            if len(set(names)) != len(names):
                dup = sorted({c for c in names if names.count(c) > 1})[0]
                raise HybridnavError(f"{where}{dup}: expected distinct column names")
            # only numeric columns can be inputs; the others are checked when named
            num = [c for c in inputs.columns if pd.api.types.is_numeric_dtype(inputs[c])
                   and not pd.api.types.is_complex_dtype(inputs[c])]
            self.columns: list[str] | None = [str(c) for c in num]
            self._other = [c for c in names if c not in self.columns]
            data = inputs[num].to_numpy(dtype=float)
        else:
            self.columns = None
            self._other = []
            data = inputs
        try:
            if np.iscomplexobj(data) or np.iscomplexobj(outputs):
                raise TypeError("complex")
            X = np.array(data, dtype=float)
            y = np.array(outputs, dtype=float).ravel()
        except (TypeError, ValueError, OverflowError):
            raise HybridnavError(f"{where}inputs, outputs: expected real numbers") from None
        if X.ndim == 1:                      # one input: a plain vector of samples
            X = X[:, None]
        if X.ndim != 2:
            raise HybridnavError(f"{where}inputs: expected an (n, k) array, got shape {X.shape}")
        if len(y) != len(X):
            raise HybridnavError(f"{where}outputs: expected {len(X)} values (one per input "
                                 f"row), got {len(y)}")
        if len(y) == 0:
            raise HybridnavError(f"{where}inputs: expected at least one sample")
        bad = ~(np.isfinite(X).all(axis=1) & np.isfinite(y))
        if bad.any():
            raise HybridnavError(f"{where}row {int(np.flatnonzero(bad)[0])}: expected finite "
                                 "numbers (NaN or inf found)")
        self.X, self.y = X, y

    @classmethod
    def from_csv(cls, path: str | Path, output: str | None = None, *, metric: str = "rmse",
                 inputs: list[str] | None = None, prefer: str | None = None) -> DataCost:
        """Samples from a CSV file with a header row: the system's inputs and its output as
        columns (``output``: the output column's name; default: the column named ``prefer``
        — the system's output — when there is one, else the last column)."""
        from hybridnav.fileio import read_text_file

        import io

        text = read_text_file(Path(path), "data file")
        import csv

        try:
            header = next(csv.reader(io.StringIO(text)), [])
        except csv.Error as exc:
            raise HybridnavError(f"{path}: not a CSV table ({exc})") from None
        header = [h.strip() for h in header]
        dup = sorted({h for h in header if header.count(h) > 1})
        if dup:
            raise HybridnavError(f"{path}: {dup[0]}: expected distinct column names in the "
                                 "header row")
        try:
            df = pd.read_csv(io.StringIO(text))
        except (ValueError, pd.errors.ParserError, OverflowError) as exc:
            raise HybridnavError(f"{path}: not a CSV table ({exc})") from None
        df.columns = [str(c).strip() for c in df.columns]
        if df.shape[1] < 2:
            raise HybridnavError(f"{path}: expected a header row with the input columns and the "
                                 f"output column, got {list(df.columns)}")
        out = output or (prefer if prefer in df.columns else str(df.columns[-1]))
        if out not in df.columns:
            raise HybridnavError(f"{path}: {out}: no such column (columns: "
                                 f"{', '.join(map(str, df.columns))})")
        cols = inputs or [c for c in df.columns if c != out]
        missing = [c for c in cols if c not in df.columns]
        if missing:
            raise HybridnavError(f"{path}: {missing[0]}: no such column")
        try:
            X = df[cols].apply(pd.to_numeric, errors="raise").astype(float)
            y = pd.to_numeric(df[out], errors="raise").astype(float)
        except (ValueError, TypeError, OverflowError) as exc:
            raise HybridnavError(f"{path}: expected numbers in every column ({exc})") from None
        return cls(X, y, metric=metric, source=str(path))

    def _ordered(self, names) -> np.ndarray:
        """The inputs as columns in the system's input order."""
        if self.columns is None:
            if self.X.shape[1] != len(names):
                raise HybridnavError(f"{self._where()}inputs: expected {len(names)} columns (the "
                                     f"system's inputs {', '.join(names)}), got "
                                     f"{self.X.shape[1]}")
            return self.X
        missing = [n for n in names if n not in self.columns]
        if missing and missing[0] in self._other:
            raise HybridnavError(f"{self._where()}{missing[0]}: expected a column of numbers")
        if missing:
            raise HybridnavError(f"{self._where()}{missing[0]}: expected a column for every input "
                                 f"of the system ({', '.join(names)}); columns: "
                                 f"{', '.join(self.columns)}")
        return self.X[:, [self.columns.index(n) for n in names]]

    def _where(self) -> str:
        return f"{self.source}: " if self.source else ""

    def check(self, settings) -> None:
        self._ordered(settings.template.input_names)

    def config(self) -> dict[str, Any]:
        import hashlib

        h = hashlib.sha256(self.X.tobytes() + self.y.tobytes()).hexdigest()
        return {"kind": "data", "metric": self.metric, "samples": len(self.y), "sha256": h,
                "columns": self.columns}

    def describe(self) -> str:
        return (f"{self.metric.upper()} against {len(self.y)} samples"
                + (f" of {self.source}" if self.source else "") + " (minimized)")

    def errors(self, candidates: Candidates) -> np.ndarray:
        """``output - sample`` of every candidate at every sample, ``(n, samples)``."""
        names = candidates.settings.template.input_names
        X = self._ordered(names)
        return candidates.evaluate({n: X[:, i] for i, n in enumerate(names)}) - self.y

    def evaluate(self, candidates: Candidates, context: Context) -> np.ndarray:
        return self.assess(candidates, context).objectives

    def assess(self, candidates: Candidates, context: Context) -> Evaluation:
        E = self.errors(candidates)
        with np.errstate(over="ignore", invalid="ignore"):
            scale = np.max(np.abs(E), axis=1, keepdims=True)       # no overflow in E * E
            safe = np.where(scale > 0, scale, 1.0)
            rmse = scale[:, 0] * np.sqrt(np.mean((E / safe) ** 2, axis=1))
        mae = np.mean(np.abs(E), axis=1)
        F = (rmse if self.metric == "rmse" else mae)[:, None]
        info = [{"rmse": float(a), "mae": float(b), "max_error": float(c)}
                for a, b, c in zip(rmse, mae, np.max(np.abs(E), axis=1))]
        return Evaluation(F, info=info)

    def subset(self, rows: np.ndarray) -> DataCost:
        """The cost on some of the samples."""
        X = self.X[rows]
        inputs = pd.DataFrame(X, columns=self.columns) if self.columns is not None else X
        return DataCost(inputs, self.y[rows], metric=self.metric, source=self.source)

    def split(self, fraction: float, seed: int) -> tuple[DataCost, DataCost]:
        if not (isinstance(fraction, float) and 0.0 < fraction < 1.0):
            raise HybridnavError(f"validation: expected a fraction in (0, 1), got {fraction!r}")
        n = len(self.y)
        n_val = int(math.floor(fraction * n))
        if n_val < 1 or n_val >= n:
            raise HybridnavError(f"validation: {fraction:g} of {n} samples leaves an empty "
                                 "training or validation part")
        perm = permutation(n, seed, 8)
        return self.subset(np.sort(perm[n_val:])), self.subset(np.sort(perm[:n_val]))

    def folds(self, k: int, seed: int) -> list[tuple[DataCost, DataCost]]:
        n = len(self.y)
        if not 2 <= k <= n:
            raise HybridnavError(f"kfold: expected 2 <= k <= {n} (the number of samples), got {k}")
        f = fold_of(n, k, seed)
        return [(self.subset(np.flatnonzero(f != j)), self.subset(np.flatnonzero(f == j)))
                for j in range(k)]
