"""The standard stability analysis of a model: every check, written as JSON, Markdown and plots.

This is what ``hybridnav analyze MODEL [--scenario S] --out DIR`` runs.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from hybridnav import __version__, models
from hybridnav.analysis.linearization import linearize, linearize_expression, summarize
from hybridnav.analysis.lyapunov import check_lyapunov, find_equilibria
from hybridnav.analysis.plots import (
    plot_basin,
    plot_eigenvalues,
    plot_lbcs_field,
    plot_phase_portrait,
    plot_sweep,
    plot_V_time,
    plot_vdot_map,
    save_figure,
)
from hybridnav.analysis.roa import basin, estimate_roa, lyapunov_equation_candidate
from hybridnav.analysis.sweep import closed_loop_sweep, grid_starts
from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_write_text, dumps_json, json_ready

log = logging.getLogger(__name__)

__all__ = ["ANALYZABLE", "analyze"]

#: initial trailer folds (theta1 - theta0, degrees) of the tractor-trailer sweep
TRAILER_FOLDS_DEG = (0, 60, 90, 120, 150)

#: Models ``analyze`` knows, and the scenario used when none is given (each model declares it)
ANALYZABLE = models.analyzable()


def analyze(model_name: str, scenario: str | None = None, out: str | Path = "analysis",
            seed: int = 0, progress: Callable[[str], None] | None = None, fmt: str = "png",
            dpi: int = 120) -> dict[str, Any]:
    """Run every check for ``model_name`` and write ``analysis.json``, ``report.md`` and plots.

    The scenario supplies the target (its first robot's goal), the region (its workspace) and, for
    ``lbcs``, the circular obstacles; a robot of the same model contributes its parameters. The
    plots are written as ``fmt`` (``png``, ``pdf``, ``svg``) at ``dpi`` dots per inch; their
    names (``analysis.json``'s ``plots``, the report's links) carry that suffix.

    Returns
    -------
    dict
        The content of ``analysis.json``.
    """
    from hybridnav.plotting.output import check_dpi, check_format, figure_name
    from hybridnav.world import load_scenario

    fmt, dpi = check_format(fmt, "fmt"), check_dpi(dpi)
    if model_name not in ANALYZABLE:
        raise HybridnavError(
            f"model: expected one of {', '.join(sorted(ANALYZABLE))}, got {model_name!r}"
        )
    scen = load_scenario(scenario or ANALYZABLE[model_name])
    robot = next((r for r in scen.robots if r.model == model_name), scen.robots[0])
    goal = robot.goal if robot.goal is not None else scen.robot(robot.goal_follow).start
    target = np.asarray(goal, dtype=float)
    cls = models.MODELS[model_name]
    if hasattr(cls, "from_scenario"):        # a scheme built on the scenario's obstacles (LbCS)
        model = cls.from_scenario(scen, robot.name)
    else:
        params = robot.params if robot.model == model_name else {}
        model = models.get(model_name, dt=scen.dt, **params)
    xmin, xmax, ymin, ymax = scen.world.workspace
    region = {"x": (xmin, xmax), "y": (ymin, ymax)}
    for name in model.state_names[2:]:
        region[name] = (-math.pi, math.pi)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    say = progress or (lambda msg: log.info(msg))
    checks: list[dict[str, Any]] = []
    plots: list[str] = []

    length = scen.units

    def plot(fig, name):
        name = figure_name(name, fmt)
        save_figure(fig, out / name, dpi=dpi)
        plots.append(name)

    say("Lyapunov check")
    rep = check_lyapunov(model, target=target, region=region, seed=seed)
    checks.append({**rep.to_dict(), "name": "lyapunov", "status": rep.status})
    fixed = dict(model.analysis_slice) or None
    gradient_flow = hasattr(model, "gradient_flow_gains")
    plot(plot_vdot_map(model, target=target, region=region, report=rep, fixed=fixed,
                       length=length), "vdot_map.png")

    if hasattr(model, "polar_error_dynamics"):
        say("LaSalle, polar error coordinates")
        checks.append(_polar_lasalle(model, target, region))

    say("linearization")
    lin = _linearizations(model, target)
    reports = {k: v.pop("_report") for k, v in lin.items() if "_report" in v}
    for name, item in lin.items():
        checks.append({**item, "name": f"linearization: {name}"})
    if reports:
        plot(plot_eigenvalues(reports), "eigenvalues.png")
    if model.smooth_at_target:
        from hybridnav.analysis.linearization import discrete_step, rk4_stability_limit

        say("simulated step")
        ds = discrete_step(model, np.asarray(target, dtype=float), target)
        limit = rk4_stability_limit()
        checks.append({"name": f"simulated step (RK4, dt = {model.dt:g}) at the target",
                       "status": "stable" if ds.stable else "unstable", **ds.to_dict(),
                       "method": f"spectral radius of the exact Jacobian of one control cycle "
                                 f"{ds.spectral_radius:.6g} ({'<' if ds.stable else '>='} 1); "
                                 f"RK4 is stable on xdot = -a x for a dt < {limit:.5f}"})

    if model.smooth_at_target:
        say("region of attraction")
        roa = estimate_roa(model, target=target, region=region, seed=seed)
        checks.append({**roa.to_dict(), "name": "region of attraction", "status": roa.status})
        levels = {"certified, V": (None, roa.level)}
        try:
            V_lyap, P = lyapunov_equation_candidate(model, target)
        except HybridnavError as exc:
            checks.append({"name": "region of attraction (control.lyap candidate)",
                           "status": "not_applicable", "reason": str(exc)})
        else:
            say("region of attraction, Lyapunov-equation candidate")
            roa2 = estimate_roa(model, V_lyap, target=target, region=region, seed=seed)
            checks.append({**roa2.to_dict(), "name": "region of attraction (control.lyap "
                           "candidate)", "status": roa2.status, "P": P.tolist()})
            levels["certified, V = dx' P dx (A'P + PA = -I)"] = (V_lyap, roa2.level)
        say("basin of attraction (simulated)")
        grid = basin(model, target=target, region=region, n=81)
        rk4 = basin(model, target=target, region=region, n=81, method="simulated")[2]
        gx, gy = np.meshgrid(grid[0], grid[1])
        free = model.admissible(np.c_[gx.ravel(), gy.ravel()]).reshape(gx.shape)
        share, share_rk4 = float(grid[2][free].mean()), float(rk4[free].mean())
        checks.append({"name": "basin of attraction (simulated grid)",
                       "status": "all_converge" if grid[2][free].all() else "partial",
                       "grid": int(free.sum()), "converged_share": share,
                       "converged_share_rk4": share_rk4,
                       "method": f"{int(free.sum())} starts on an 81 x 81 grid over the "
                                 "workspace (outside the obstacles): "
                                 f"{100 * share:.1f} % converge under the closed-loop ODE "
                                 f"(CVODES), {100 * share_rk4:.1f} % under the simulated RK4 "
                                 f"step at dt = {model.dt:g}"})
        plot(plot_basin(model, target=target, region=region, levels=levels, basin_grid=grid,
                        length=length), "basin.png")
    if gradient_flow:
        say("stationary points")
        eqs = find_equilibria(model, target=target, region=region, seed=seed)
        others = [e for e in eqs if not e.is_target]
        checks.append({"name": "stationary points other than the target",
                       "status": "found" if others else "none_found",
                       "points": [e.to_dict() for e in others]})
        tr = model.rollout(np.array([robot.start]), target[None], scen.max_steps)
        final = tr[0, -1]
        stalled = float(np.hypot(*(final - target))) > robot.goal_radius
        checks.append({"name": "LbCS run from the scenario's start",
                       "status": "stalled" if stalled else "reached",
                       "start": list(robot.start), "final_state": final.tolist()})
        plot(plot_lbcs_field(model, target=target, region=region, equilibria=eqs,
                             trajectories=tr, length=length), "lbcs_field.png")
    else:
        plot(plot_phase_portrait(model, target=target, region=region, fixed=fixed,
                                 length=length), "phase_portrait.png")

    say("closed-loop sweep")
    table, traj, Vt = _sweep(model, target, region, scen)
    table.to_csv(out / "sweep.csv", index=False)
    summary = {"runs": len(table), "reached": int(table["reached"].sum()),
               "V_monotone": int(table["V_monotone"].sum())}
    if "jackknife" in table:
        summary.update(jackknife=int(table["jackknife"].sum()),
                       max_gap=float(table["max_gap"].max()))
    if "fold_deg" in table:
        summary["by_fold"] = {str(int(f)): {"runs": int(len(g)), "reached": int(g["reached"].sum()),
                                            "jackknife": int(g["jackknife"].sum())}
                              for f, g in table.groupby("fold_deg")}
    checks.append({"name": f"closed-loop sweep (V = {model.candidate_name})",
                   "status": "all_monotone" if summary["V_monotone"] == summary["runs"]
                   else "not_all_monotone", **summary})
    plot(plot_sweep(table, traj, target=target, title=f"{model_name}: closed-loop sweep",
                    length=length), "sweep.png")
    t = np.arange(Vt.shape[1]) * model.dt
    pick = np.linspace(0, len(Vt) - 1, min(12, len(Vt))).astype(int)
    # a family of runs: coloured by how far from the target each started
    start_distance = np.hypot(*(traj[pick, 0, :2] - target).T)
    from hybridnav.plotting.labels import axis_label

    plot(plot_V_time(t, Vt[pick], title=f"V along {len(pick)} of the sweep's {len(Vt)} runs",
                     color_by=start_distance,
                     color_label=axis_label("start's distance to the target", "length", length),
                     v_label=axis_label(f"V = {model.candidate_name}",
                                        getattr(model, "candidate_unit", None), length)),
         "V_time.png")

    result = {"model": model_name, "params": model.values, "scenario": scen.name,
              "target": target.tolist(), "region": {k: list(v) for k, v in region.items()},
              "seed": seed, "version": __version__, "checks": checks, "plots": plots}
    result = json_ready(result)
    atomic_write_text(out / "analysis.json", dumps_json(result))
    atomic_write_text(out / "report.md", _markdown(result, table, fmt))
    return result


def _polar_lasalle(model, target, region) -> dict[str, Any]:
    """LaSalle's argument for V = 1/2 rho^2 on the polar error dynamics (smooth in rho, e)."""
    import casadi as cs

    from hybridnav.analysis.certificate import certify
    from hybridnav.analysis.region import Box

    z, zdot, names = model.polar_error_dynamics()
    zdot = cs.substitute(zdot, model.sym.p, cs.DM(model.p_value()))
    corners = [(region["x"][i], region["y"][j]) for i in (0, 1) for j in (0, 1)]
    rmax = max(math.hypot(cx - target[0], cy - target[1]) for cx, cy in corners)
    box = Box(names, np.array([0.0, -math.pi]), np.array([rmax, math.pi]))
    cert = certify(z, zdot, 0.5 * z[0] ** 2, box, lasalle=True)
    return {"name": "LaSalle: V = 1/2 rho^2 in polar error coordinates (rho, e)",
            **cert.to_dict(), "method": cert.method}


def _linearizations(model, target) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}

    def add(name, thunk, point):
        try:
            rep = summarize(thunk(), point)
        except HybridnavError as exc:
            out[name] = {"status": "not_differentiable", "reason": str(exc)}
            return
        out[name] = {"status": "stable" if rep.stable else "not_asymptotically_stable",
                     **rep.to_dict(), "_report": rep}

    x0 = np.zeros(model.nx)
    x0[:2] = target
    polar = hasattr(model, "polar_error_dynamics")
    if model.smooth_at_target or polar:
        add("closed loop at the target" + (" (Cartesian)" if polar else ""),
            lambda: linearize(model, x0, target=target), dict(zip(model.state_names, x0)))
    if polar:
        z, zdot, names = model.polar_error_dynamics()
        add("closed loop at the target (polar error coordinates rho, e)",
            lambda: linearize_expression(z, zdot, [0.0, 0.0], names, symbols=model.sym.p,
                                         values=model.p_value(), name=f"{model.name}_polar"),
            {"rho": 0.0, "e": 0.0})
    if model.straight_driving is not None:
        u0 = list(model.straight_driving)
        zero = [0.0] * model.n_plant
        label = ", ".join(f"{n} = {v:g}" for n, v in zip(model.input_names, u0))
        add(f"open loop, straight driving ({label})", lambda: linearize(model, zero, u0),
            dict(zip(model.plant_state_names, zero)))
    return out


def _sweep(model, target, region, scen):
    """Starts on a grid over the workspace, every 45 degrees of heading."""
    xs = np.linspace(*region["x"], 9)[1:-1]
    ys = np.linspace(*region["y"], 9)[1:-1]
    pos = np.array([(x, y) for x in xs for y in ys
                    if math.hypot(x - target[0], y - target[1]) > 1e-9])
    headings = np.linspace(-math.pi, math.pi, 8, endpoint=False)
    init: dict[str, Any] = {}
    if "theta" in model.state_names:
        init = {"theta": headings}
    elif "theta0" in model.state_names:
        init = {"theta0": headings, "theta1": "theta0"}
    X0, starts = grid_starts(model, target, pos, init)
    if "theta1" in model.state_names:
        # the trailer also starts folded (theta1 = theta0 + fold), so the jackknife claims are
        # checked here and not only with the trailer aligned
        i1 = model.state_names.index("theta1")
        parts, tables = [], []
        for fold in TRAILER_FOLDS_DEG:
            X = X0.copy()
            X[:, i1] = X0[:, i1] + math.radians(fold)
            parts.append(X)
            tables.append(starts.assign(fold_deg=fold, theta1=starts["theta1"] + math.radians(fold)))
        X0 = np.vstack(parts)
        starts = pd.concat(tables, ignore_index=True)
    keep = model.admissible(X0)
    X0, starts = X0[keep], starts[keep].reset_index(drop=True)
    steps = min(scen.max_steps, 3000)
    table, traj, Vt = closed_loop_sweep(model, X0, target=target, steps=steps,
                                        goal_radius=scen.robots[0].goal_radius)
    return starts.join(table), traj, Vt


def _markdown(result: dict[str, Any], table, fmt: str = "png") -> str:
    from hybridnav.plotting.output import figure_name

    lines = [f"# Stability analysis: {result['model']}", "",
             f"Scenario `{result['scenario']}`, target {result['target']}, region "
             f"{result['region']}, seed {result['seed']}, hybridnav {result['version']}.", "",
             "| check | status | how / numbers |", "|---|---|---|"]
    for c in result["checks"]:
        how = c.get("method") or c.get("reason") or ""
        if "eigenvalues" in c and c["name"].startswith("linearization"):
            how = "eigenvalues " + ", ".join(f"{re:.4g}{im:+.4g}j" for re, im in c["eigenvalues"])
            if c.get("n_inputs", 1):
                how += f"; controllability rank {c['controllability_rank']} of {c['n_states']}"
            else:
                how += "; no inputs (the closed loop): controllability does not apply"
        if c["name"].startswith("region of attraction") and "bounded_by" in c:
            lev = "unbounded (the proof is global)" if c["level"] is None else \
                f"level {c['level']:.6g} (bounded by: {c['bounded_by']})"
            how = (f"{lev}; {c['converged']}/{c['simulated']} simulated starts converged, "
                   f"{c['monotone']} monotone")
            if c["details"].get("claim"):
                how += f". Proved: {c['details']['claim']}"
        if c.get("claim") and c["claim"] not in how:
            how += f". Proved: {c['claim']}"
        if c["name"].startswith("closed-loop sweep"):
            how = f"{c['reached']}/{c['runs']} reached, {c['V_monotone']} with V monotone"
            if "jackknife" in c:
                how += f", {c['jackknife']} jackknifed (max |th0 - th1| {c['max_gap']:.3f} rad)"
            if "by_fold" in c:
                how += "; by initial fold: " + ", ".join(
                    f"{f} deg {v['reached']}/{v['runs']} reached, {v['jackknife']} jackknifed"
                    for f, v in c["by_fold"].items())
        if c["name"].startswith("stationary points"):
            how = "; ".join(f"{p['kind']} at ({p['state'][0]:.4g}, {p['state'][1]:.4g})"
                            for p in c["points"]) or "none"
        if "final_state" in c:
            how = f"from {c['start']} it ends at {[round(v, 4) for v in c['final_state']]}"
        lines.append(f"| {c['name']} | **{c['status']}** | {how.replace('|', '/')} |")
    lines += ["", "What the Lyapunov statuses mean:", "",
              "- **proved**: an exact argument, and the row says what was proved on which set: "
              "quadratic forms centred exactly on the equilibrium with Hessians definite by "
              "interval eigenvalue bounds (global); an "
              "interval branch-and-bound certificate (V > 0 and Vdot < 0 on every box of the "
              "set, the equilibrium's neighbourhood by interval bounds on the Hessians); or "
              "LaSalle's invariance principle (Vdot <= 0 proved, and no trajectory can stay "
              "where Vdot = 0, so trajectories end near V = 0).",
              "- **counterexample**: a state where V < 0 or Vdot >= 0 away from the "
              "equilibrium, claimed only where the interval enclosure of V or Vdot at that "
              "state shows the sign (its V, Vdot and enclosures are printed).",
              "- **no_counterexample**: dense sampling, an optimizer, the local check at the "
              "equilibrium and (up to 3 states) the certificate's branch and bound found none, "
              "but the certificate did not close. Evidence, not a proof.",
              "- **undecided**: rounding would decide (a Hessian eigenvalue that cannot be told "
              "from zero, or Vdot zero to rounding at a state: its enclosure holds 0, as where "
              "Vdot vanishes on a curve), or a proof disagreed with the samples; no claim is "
              "made.", "",
              "A region of attraction's **proved** is the same kind of argument on the level "
              "set it names (the certificate route); its simulated starts only confirm it. The "
              "basin row simulates a grid of starts: the true region of attraction, against "
              f"which the certified level sets are drawn in {figure_name('basin', fmt)}.", ""]
    lines += ["", "Plots: " + ", ".join(f"[{p}]({p})" for p in result["plots"]), ""]
    if "max_gap" in table:
        worst = table.sort_values("max_gap", ascending=False).head(10)
        lines += ["## Largest trailer angles in the sweep", "", _md_table(worst), ""]
    return "\n".join(lines)


def _md_table(df) -> str:
    """A DataFrame as a Markdown table (numbers to 4 significant digits)."""
    def cell(v):
        return f"{v:.4g}" if isinstance(v, (float, np.floating)) else str(v)

    rows = ["| " + " | ".join(map(str, df.columns)) + " |", "|" + "---|" * len(df.columns)]
    rows += ["| " + " | ".join(cell(v) for v in r) + " |" for r in df.itertuples(index=False)]
    return "\n".join(rows)
