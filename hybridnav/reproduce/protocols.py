"""The papers' protocols: what each reproduction runs, the paper's numbers and the paper's claims.

A :class:`Protocol` names the compared planners (every planner with profiles runs in both, the
``paper`` and the ``hybridnav`` one; the others once), the scenarios standing for the paper's
rows, the paper's number of runs, parameter settings the paper states (``settings``), ablation
variants, the paper's reported values per row and planner, and its :class:`Claim` s, which the
report checks on the paper's own numbers and on ours.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["JITTER", "PROTOCOLS", "STORE", "Claim", "Protocol", "Row", "Value"]


@dataclass(frozen=True)
class Value:
    """What a paper reports for one planner in one row: time (s), length (the scenario's units)
    and the outcome when it gives only that (``"reached"``/``"stuck"``)."""

    time: float | None = None
    length: float | None = None
    outcome: str = "reached"


@dataclass(frozen=True)
class Row:
    """One row of a paper's table: its label there, our scenario, the paper's values by planner
    and, where the paper quotes them, its best and worst runs by planner (``extremes``:
    ``{planner: (best, worst)}``, each the run's time and length; the report sets our best and
    worst run beside them, the shortest and the longest reached path with its own time)."""

    label: str
    scenario: str
    paper: dict[str, Value]
    extremes: dict[str, tuple[Value, Value]] = field(default_factory=dict)


@dataclass(frozen=True)
class Claim:
    """A paper's claim about two planners (``kind``: ``shorter`` or ``faster``: ``a`` beats ``b``
    in mean length / time on every listed row; ``worst-case``: ``a``'s worst run beats ``b``'s in
    length and in time) or one (``reaches``: every run of ``a`` reaches its goal; ``stuck``: every
    run of ``a`` ends trapped, stuck or at the time limit, none reaching, colliding or leaving; ``collision-free``: every robot of every run reaches its goal and none collides, with an
    obstacle or another robot). :mod:`hybridnav.reproduce.report` defines each precisely.
    ``rows``: the row labels it covers (empty: all).
    ``time``: which time a ``faster`` claim means, as the paper defines it: ``"simulated"`` (the
    robot's travel time) or ``"with planning"`` (travel plus the planner's computation).
    ``time_source``: where the paper says so."""

    text: str
    kind: str
    a: str
    b: str = ""
    rows: tuple[str, ...] = ()
    time: str = "simulated"
    time_source: str = ""

    def __post_init__(self) -> None:
        if self.time not in ("simulated", "with planning"):
            raise ValueError(f"claim {self.text!r}: time: expected 'simulated' or "
                             f"'with planning', got {self.time!r}")
        if self.kind == "worst-case" and self.time != "simulated":
            raise ValueError(f"claim {self.text!r}: a worst-case claim compares the worst run's "
                             "simulated time (the summary keeps no other)")


@dataclass(frozen=True)
class Protocol:
    """One paper's comparison, as ``hybridnav reproduce NAME`` runs it."""

    name: str
    paper: str
    source: str                      # where in the paper
    planners: tuple[str, ...]
    rows: tuple[Row, ...]
    runs: int
    claims: tuple[Claim, ...]
    settings: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: ablation variants, ``(label, planner, params)``, run with the default profile
    ablations: tuple[tuple[str, str, dict[str, Any]], ...] = ()
    #: ``(a, b)``: recompute the paper's enhancement percentages ``100 (b - a) / b``
    enhancement: tuple[str, str] | None = None
    #: values the paper quotes from other work (not run here): ``{row label: {method: length}}``
    literature: dict[str, dict[str, float]] = field(default_factory=dict)
    notes: str = ""
    #: where the paper contradicts itself (its tables, text and conclusion), each with which
    #: version the protocol uses and why; the report lists them before the results
    conflicts: tuple[str, ...] = ()
    #: ``(parameter, values)``: every variant whose planner declares ``parameter`` runs once per
    #: value, labelled ``LABEL/parameter=value`` (e.g. sensor noise levels); the others run once
    sweep: tuple[str, tuple[Any, ...]] | None = None
    #: what the paper ran, in words, where ``runs`` is not its number (a paper that shows one run
    #: as a figure: ``runs`` is ours, chosen to see how typical that run is)
    paper_runs: str = ""


#: layout sensitivity (:mod:`hybridnav.reproduce.layouts`): how far starts and obstacles move,
#: as a fraction of the start-goal distance
JITTER = 0.05
#: where the full runs are kept, relative to the repository's root
STORE = Path("docs") / "reproductions"

FASTEP = "Chaudhary, Prasad, Prasad & Sharma, IEEE Access 2024 (FAStep-Kinematic)"
ACOK = "Chaudhary, Prasad, Chand & Sharma, PeerJ CS 2022 (ACO-Kinematic)"
RFDPSO = "Hassen, Amin & Al-Araji, IJRITCC 2023 (RFD-PSO)"
EFFC = "Golkhatib, Shahmansoorian & Davoudi, IJEEE 2025 (EFFC)"
PSOBA = "Abed, Hameed, Al-Araji et al., IJ-AI 2022 (PSO-BA)"

PROTOCOLS: dict[str, Protocol] = {p.name: p for p in (
    Protocol(
        name="fastep-table2", paper=FASTEP, source="Table 2 (30 runs per scenario), Section V",
        planners=("fastep-kinematic", "aco-kinematic"),
        rows=(Row("scenario 1", "fastep-s1", {"fastep-kinematic": Value(69.62, 56.56),
                                              "aco-kinematic": Value(133.76, 56.77)}),
              Row("scenario 2", "fastep-s2", {"fastep-kinematic": Value(154.04, 59.69),
                                              "aco-kinematic": Value(283.25, 65.75)}),
              Row("scenario 3", "fastep-s3", {"fastep-kinematic": Value(95.80, 45.73),
                                              "aco-kinematic": Value(173.27, 48.54)})),
        runs=30,
        claims=(Claim("FAStep-Kinematic's mean path is shorter than ACO-Kinematic's in all three "
                      "scenarios", "shorter", "fastep-kinematic", "aco-kinematic"),
                Claim("FAStep-Kinematic reaches the goal in less time than ACO-Kinematic in all "
                      "three scenarios", "faster", "fastep-kinematic", "aco-kinematic",
                      time="with planning",
                      time_source="Sec. VIII: \"generation of each point takes time\"")),
        enhancement=("fastep-kinematic", "aco-kinematic"),
        notes="The scenarios are reconstructions of the paper's figures."),
    Protocol(
        name="aco-table5", paper=ACOK, source="Tables 3-5 and scenario 4 (Figs. 18-19)",
        planners=("aco-kinematic", "lbcs"),
        rows=(Row("scenario 1", "fastep-s1", {"lbcs": Value(251.02, 58.57),
                                              "aco-kinematic": Value(208.72, 57.98)},
                  extremes={"aco-kinematic": (Value(201.4, 57.81), Value(210.57, 58.29))}),
              Row("scenario 2", "aco-s2", {"lbcs": Value(309.44, 66.3),
                                              "aco-kinematic": Value(124.99, 65.35)},
                  extremes={"aco-kinematic": (Value(138.14, 64.5), Value(101.28, 66.28))}),
              Row("scenario 3", "tractor-trailer-1", {"lbcs": Value(240.92, 68.34),
                                                      "aco-kinematic": Value(195.79, 66.27)},
                  extremes={"aco-kinematic": (Value(230.02, 62.99), Value(238.05, 68.06))}),
              Row("scenario 4", "aco-scenario-4", {"lbcs": Value(outcome="stuck"),
                                                   "aco-kinematic": Value()})),
        runs=30,
        settings={"aco-kinematic": {"a": 0.02, "c": 0.05}},
        claims=(Claim("ACO-Kinematic's path is shorter than LbCS's", "shorter", "aco-kinematic",
                      "lbcs", ("scenario 1", "scenario 2", "scenario 3")),
                Claim("ACO-Kinematic reaches the goal in less time than LbCS", "faster",
                      "aco-kinematic", "lbcs", ("scenario 1", "scenario 2", "scenario 3")),
                Claim("LbCS is trapped in the local minimum of scenario 4", "stuck", "lbcs",
                      rows=("scenario 4",)),
                Claim("ACO-Kinematic reaches the goal of scenario 4", "reaches", "aco-kinematic",
                      rows=("scenario 4",)),
                Claim("In scenario 1, ACO-Kinematic's worst-case path length and time are better "
                      "than LbCS's", "worst-case", "aco-kinematic", "lbcs", ("scenario 1",))),
        enhancement=("aco-kinematic", "lbcs"),
        notes=("Table 3's weights (a = 0.02, c = 0.05) are set for ACO-Kinematic; LbCS is "
               "deterministic (the paper ran it once, so its one run is its best and its worst). "
               "Scenario 4's cup is our reconstruction (aco-scenario-4); the other layouts "
               "reconstruct the paper's figures. The best and worst runs are the paper's text "
               "under Table 5 (the shortest and the longest path, each with its own time).")),
    Protocol(
        name="rfdpso-table3", paper=RFDPSO, source="Table 2 (700 x 700 cm map), Table 3 "
                                                   "(20 x 20 m map), Table 4 (20 x 20 alley "
                                                   "map), Figs. 6-14",
        planners=("rfd", "pso", "rfd-pso", "astar", "dijkstra"),
        rows=(Row("700 x 700 cm", "rfd-pso-700", {"rfd": Value(length=596.69),
                                                  "pso": Value(length=626.82),
                                                  "rfd-pso": Value(length=628.86)}),
              Row("20 x 20 m", "rfd-pso-20m", {"rfd": Value(length=32.68),
                                               "pso": Value(length=44.96),
                                               "rfd-pso": Value(length=29.58)}),
              Row("alley map", "rfd-pso-alley", {"astar": Value(length=33.48),
                                                 "dijkstra": Value(length=33.48),
                                                 "rfd": Value(length=117.12),
                                                 "pso": Value(length=45.20),
                                                 "rfd-pso": Value(length=31.65)})),
        runs=10,
        ablations=(("rfd-pso/no-shorten", "rfd-pso", {"shorten": False}),
                   ("rfd/shortened", "rfd", {"shorten": True}),
                   ("astar/shortened", "astar", {"shorten": True})),
        claims=(Claim("RFD-PSO's path is shorter than RFD's", "shorter", "rfd-pso", "rfd"),
                Claim("RFD-PSO's path is shorter than PSO's", "shorter", "rfd-pso", "pso"),
                Claim("RFD-PSO's path is shorter than A*'s (Table 4)", "shorter", "rfd-pso",
                      "astar", ("alley map",)),
                Claim("RFD-PSO's path is shorter than Dijkstra's (Table 4)", "shorter",
                      "rfd-pso", "dijkstra", ("alley map",))),
        literature={"20 x 20 m": {"SAACO [28]": 29.796, "FACO [29]": 29.3848},
                    "alley map": {"ACO [22]": 138.98, "ACO* [22]": 87.49}},
        notes=("Lengths are travelled path lengths. The maps are reconstructions. With the "
               "paper's start (80, 450) and goal (600, 100) the straight line is 626.82 cm: the "
               "paper's PSO length is that line to 4 digits and its RFD length is below it, so "
               "no layout has both paths; ours blocks the line. The ablations separate the "
               "PSO's gain from the shortening (pulling the path tight), which the paper does "
               "not have. Table 4 gives its lengths in cm on a '20 x 20 m' alley map; they read "
               "as grid cells (Dijkstra's and A*'s 33.48 is 25 straight and 6 diagonal moves), "
               "and our alley map is built so that its grid optimum is exactly that; the "
               "planners keep their default 0.25-cell margin."),
        conflicts=(
            "Table 2 against the text (700 x 700 cm map): the extracted Table 2 has the hybrid "
            "shortest, 596.8554 cm, beside 626.8174 cm for RFD and 628.69 cm for PSO (as far as "
            "the garbled extraction shows its rows), as the text's claim that the hybrid route "
            "was the most efficient says; the text (Figs. 6-8) gives RFD 596.69 cm, PSO "
            "626.8174 cm, RFD-PSO 628.8554 cm. The table's numbers mix the text's digits (596 of "
            "RFD with .8554 of the hybrid, 628 of the hybrid with .69 of RFD). We use the text: "
            "each of its numbers is stated with the figure it comes from, and its PSO length is "
            "the straight line between the stated start and goal (626.817 cm), which the text "
            "gets right. So in the paper's numbers the hybrid is the longest on this map and "
            "the claims that it is shorter than RFD and PSO do not hold there (with the table "
            "they would). Either version has a length below that straight line (the text's RFD "
            "596.69, the table's hybrid 596.8554), which no path between the stated start and "
            "goal has.",
            "Table 3 against the paper's claim that RFD-PSO offers the shortest path among the "
            "compared works: in its own Table 3 FACO [29] (29.3848 m) is shorter than RFD-PSO "
            "(29.5753 m, 0.65 % longer); only SAACO (29.796 m) is longer. We quote SAACO and FACO "
            "as printed (not run) and check no claim against them; the claims we check compare "
            "RFD-PSO with the planners we run.",
            "The conclusion's percentages match neither table. Recomputed as 100 (b - a) / b "
            "from the tables (a the first-named): RFD against SAACO -9.68 % and against FACO "
            "-11.21 % (Table 3: RFD is the longer, not '27.43 %' and '23.25 %'); RFD against ACO "
            "15.73 % and against ACO* -33.87 % (Table 4: RFD is longer than ACO*, not '24.48 %' "
            "and '7 %' better); RFD-PSO against RFD 9.50 % (Table 3), 72.98 % (Table 4) and "
            "-5.39 % (Table 2 as the text gives it; 4.78 % as the table does), not '0.34 %'; "
            "RFD-PSO against PSO 34.21 % on the complex map (Table 3), 29.98 % (Table 4) and "
            "-0.33 % (Table 2, text; 5.06 % table), not '13.2 %'. We report none of the "
            "conclusion's figures and judge the claims on the tables' lengths.",
            "Table 4 gives 100 repetitions for every method (Dijkstra's and A* included) on the "
            "alley map, while Figs. 7, 8, 10 and 11 give the PSO and the hybrid a maximum of 50 "
            "repetitions (iterations) on the other two maps. The paper profile uses 50 PSO "
            "iterations on all three maps: a profile is one setting per planner, 50 is the "
            "limit the text states with the cost curves it comes from, and a column that gives "
            "the deterministic searches 100 repetitions too does not read as the PSO's "
            "iteration limit.",
        )),
    Protocol(
        name="effc-table3", paper=EFFC, source="Table 3",
        planners=("effc", "hapf", "pbpf"),
        rows=(Row("environment (a)", "effc-env-a", {"effc": Value(11.5, 2.3),
                                                    "hapf": Value(15.5, 3.1),
                                                    "pbpf": Value(13.1, 2.6)}),
              Row("environment (b)", "effc-env-b", {"effc": Value(12.2, 2.4),
                                                    "hapf": Value(14.3, 2.8),
                                                    "pbpf": Value(13.5, 2.7)})),
        runs=10,
        settings={name: {"speed": 0.2} for name in ("effc", "hapf", "pbpf")},
        ablations=(("effc/tuned", "effc", {"fis": "effc-tuned"}),),
        claims=(Claim("EFFC's path is shorter than HAPF's", "shorter", "effc", "hapf"),
                Claim("EFFC's path is shorter than PBPF's", "shorter", "effc", "pbpf"),
                Claim("EFFC reaches the goal in less time than HAPF", "faster", "effc", "hapf"),
                Claim("EFFC reaches the goal in less time than PBPF", "faster", "effc", "pbpf")),
        enhancement=("effc", "hapf"),
        notes=("The environments are reconstructions (the paper shows them only in Fig. 20), "
               "built so that every length the paper reports is possible in them (see the "
               "bounds below). The speed is the 0.2 m/s that Table 3's lengths and times imply "
               "(2.3 m in 11.5 s; a TurtleBot3 tops out at 0.22 m/s); the paper's training ran "
               "at 0.1 m/s, the planners' default.")),
    Protocol(
        name="psoba-fig15", paper=PSOBA, source="Section 6 and Fig. 15 (one sample run)",
        planners=("pso-ba",),
        rows=(Row("Fig. 15", "pso-ba-dynamic", {"pso-ba": Value()}),),
        runs=1,
        claims=(Claim("Both robots reach their targets without a collision (robot 1 its fixed "
                      "goal, robot 2 the moving robot 1) among static and moving obstacles",
                      "collision-free", "pso-ba"),),
        notes=("The paper shows one sample run and gives no table: robot 2 meets robot 1 at its "
               "88th iteration (one path point per iteration), and at iteration 51 it prints "
               "distance 89, smoothness 196, fitness 0.441. Its step length is not given, so "
               "iteration counts are not comparable with our path points. The layout is a "
               "reconstruction (start, goals and the robots from the text; the obstacles ours). "
               "PSO-BA's swarm barely matters here: its fitness has no obstacle term, so other "
               "seeds give almost the same paths.")),
    Protocol(
        name="effc-turtlebot", paper=EFFC,
        source="Section 4, the real-robot experiment (TurtleBot3, Figs. 17-19; no table), as a "
               "simulation stand-in",
        planners=("effc", "hapf", "apf"),
        rows=(Row("office (Fig. 17)", "turtlebot-office", {"effc": Value()}),),
        runs=10,
        settings={"effc": {"speed": 0.22, "sensor": "lidar"},
                  "apf": {"speed": 0.22, "sensor": "lidar"},
                  "hapf": {"speed": 0.22}},
        ablations=(("effc/tuned", "effc", {"fis": "effc-tuned"}),),
        sweep=("sensor_noise", (0.0, 0.01, 0.03, 0.05)),
        claims=(Claim("EFFC drives the TurtleBot3 to the goal without a collision in an office "
                      "setting (Sec. 4: the real-time implementation 'validated the "
                      "effectiveness of the approach in practical scenarios')", "collision-free",
                      "effc"),
                Claim("The GA-tuned EFFC reaches the goal without a collision whatever the "
                      "range noise (abstract: the GA is to 'enhance adaptability and robustness "
                      "to sensor uncertainties')", "collision-free", "effc/tuned"),
                Claim("EFFC's path is shorter than HAPF's (the paper's simulated comparison, "
                      "Table 3 and the conclusion, carried over to the office)", "shorter",
                      "effc", "hapf")),
        notes=("A simulation stand-in for the paper's real TurtleBot3 run, which it shows only "
               "as a photo, a trajectory and a control-effort plot (Figs. 17-19): no layout, "
               "speed, sensor model or number. The office map is ours (`turtlebot-office`: two "
               "rooms, a corridor, 0.8 m doorways, furniture). The robot is a unicycle with a "
               "TurtleBot3 Burger's radius (0.105 m) and limits, v <= 0.22 m/s and omega <= "
               "2.84 rad/s, saturated in the model; the planners drive at 0.22 m/s (its top "
               "speed; the paper gives none for this run), and the turn-rate limit binds "
               "wherever the heading controller asks for more than 0.284 rad per 0.1 s cycle. "
               "The settings above are ours, not the paper's. "
               "EFFC and APF find their nearest obstacle with a simulated LDS-01 (`sensor = "
               "lidar`: 360 beams 1 degree apart from the robot's centre, returns within "
               "0.12-3.5 m, one scan per 0.1 s cycle, Gaussian range noise of standard "
               "deviation `sensor_noise` (m) drawn from the run's seed); HAPF plans on the "
               "known map, so it has no sensor and runs once. What differs from the real "
               "experiment: perfect localization and odometry (no SLAM, no wheel slip), no "
               "motor or scan latency, no dynamics beyond the saturation (0.22 m/s and "
               "2.84 rad/s are applied separately, not as the wheels' joint limit), "
               "independent noise per beam and scan (no bias, no dropouts but at the range "
               "limits), walls and furniture as ideal shapes. Control effort is the sum over "
               "control cycles of (v^2 + omega^2) dt of the commands (the paper's Figs. 16 "
               "and 19 plot the angular velocity). The paper gives no numbers for this run, "
               "so its claims are the text's qualitative ones.")),
    Protocol(
        name="fastep-case-studies", paper_runs="one run, Fig. 5", paper=FASTEP,
        source="Section VII-B, case study 2 (Fig. 5: two point masses avoiding each other)",
        planners=("fastep-kinematic",),
        rows=(Row("case study 2 (Fig. 5)", "fastep-case-study-2",
                  {"fastep-kinematic": Value()}),),
        runs=30,
        claims=(Claim("Both robots reach their targets, avoiding the obstacles and each other "
                      "(each is a moving obstacle to the other)", "collision-free",
                      "fastep-kinematic"),),
        notes=("The paper shows one run (Fig. 5) and gives no numbers: R1 (5, 5) -> (45, 45) "
               "and R2 (45, 45) -> (5, 5) head-on, the two \"avoid collision at point (30, 22)\". "
               "We run it 30 times, as the paper's Table 2, to see how often that holds. Table "
               "1's parameters are FAStep-Kinematic's defaults. The layout is a reconstruction "
               "(the circles of tractor-trailer-1).")),
    Protocol(
        name="aco-case-studies", paper_runs="one run, Fig. 3", paper=ACOK,
        source="case study 2 (Figs. 3-4: three point masses avoiding each other)",
        planners=("aco-kinematic",),
        rows=(Row("case study 2 (Fig. 3)", "aco-case-study-2", {"aco-kinematic": Value()}),),
        runs=30,
        claims=(Claim("The three robots reach their targets, avoiding all obstacles and each "
                      "other", "collision-free", "aco-kinematic"),),
        notes=("The paper shows one run (Figs. 3-4) and gives no numbers: R1 (5, 45) -> "
               "(45, 5), R2 (5, 5) -> (45, 45), R3 (45, 25) -> (5, 25) among circles and "
               "rectangles. We run it 30 times, as the paper's Table 5, to see how often that "
               "holds. Table 1's weights (a = b = c = 0.18, d = 0.01, the case studies' "
               "parameters) are ACO-Kinematic's defaults. The layout is a reconstruction.")),
    Protocol(
        name="aco-tractor-trailers", paper_runs="one run per case, a figure each", paper=ACOK,
        source="the tractor-trailer application: Figs. 6-7 (one robot), Table 2 and Figs. 8-11 "
               "(three robots), Table 3's tractor-trailer weights",
        planners=("aco-kinematic",),
        rows=(Row("Fig. 6", "tractor-trailer-2", {"aco-kinematic": Value()}),
              Row("Fig. 7", "tractor-trailer-1", {"aco-kinematic": Value()}),
              Row("Table 2 (Figs. 8-11)", "tractor-trailer-3", {"aco-kinematic": Value()})),
        runs=5,
        settings={"aco-kinematic": {"a": 0.02, "c": 0.18}},
        claims=(Claim("One tractor-trailer reaches its target avoiding the obstacles (Figs. 6-7)",
                      "collision-free", "aco-kinematic", rows=("Fig. 6", "Fig. 7")),
                Claim("The three tractor-trailers reach their targets, avoiding the obstacles "
                      "and each other (Figs. 8-11)", "collision-free", "aco-kinematic",
                      rows=("Table 2 (Figs. 8-11)",))),
        notes=("The paper shows one run per case (a figure each) and gives no numbers; we run "
               "5 (a tractor-trailer step rolls the model out for every candidate, and 5 runs "
               "show whether the figure's run is typical). Table 3's tractor-trailer weights "
               "(a = 0.02, c = 0.18) are set for ACO-Kinematic. Figs. 6-7: (5, 5) -> (45, 45) "
               "and (5, 45) -> (45, 5); Table 2: R1 (5, 45) -> (45, 5), R2 (5, 25) -> (45, 25), "
               "R3 (5, 5) -> (45, 45) (our TT1-TT3). The layouts are reconstructions "
               "(tractor-trailer-1 is also Table 5's scenario 3). That R1 stops and waits for R3 "
               "(Fig. 8) is a behaviour of one run that the summary does not measure: see the "
               "run-0 paths figure."),
        conflicts=("The text says Fig. 8 shows R1 avoiding R3 by stopping and waiting for R3 to "
                   "pass; the captions of Figs. 8-9 say R3 avoids R1. The claim checked here "
                   "(every robot reaches, none touches an obstacle or another robot) is the "
                   "same either way.",
                   "The text says Fig. 10 shows R2 and R3 avoiding each other; its caption says "
                   "R1 avoids R2. The same claim either way.",
                   "Table 1 gives a = 0.18 as the parameters \"used in the three case studies\" "
                   "(the tractor-trailer application is the third); Table 3 gives the "
                   "tractor-trailer a = 0.02, c = 0.18. We use Table 3, the paper's tuned "
                   "tractor-trailer values.")),
)}
