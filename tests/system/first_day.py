#!/usr/bin/env python3
"""The first day, checked: runs the commands README.md and docs/*.md show, as they show them, and
compares the figures the docs print beside them with what the commands print, at the docs'
printed precision.

The docs stay the only place the figures are written. This file says, per documented run, which
commands it is (each must appear verbatim in its doc, or the check fails) and, per figure, the
doc's words around it (`{}` where the figure stands, any run of spaces or a line break matching
any other) and where in the commands' output its value is. A figure is the same when the two
printed numbers can round to one value: |doc − code| ≤ half a unit of the doc's last digit plus
half a unit of the code's last printed digit (full precision from JSON).

Usage: tests/system/first_day.py [--build DIR] [--work DIR] [--only RUN,…] [--slow | --slow-only]
                                 [--print] [--again] [--list]
  --build  the build tree (default build): its bin/ is the documented build/bin/
  --work   where the commands run (default BUILD/first-day): build, tools, tests and robots are
           linked there so that the docs' command lines run as written, their out/ there
  --only   these runs alone (names: --list)
  --slow   the runs marked slow too (the real UR10's diagnosis, its twin and series, the planning
           comparison's failing run; about 2.5 min on 2 idle cores)
  --slow-only  those alone
  --print  every figure: doc and line, the doc's value, the code's value, and whether they agree
  --again  compare again with the outputs the last run in WORK kept, running nothing (while
           bringing the docs to new figures; the check itself always runs the commands)
  --list   the runs and their commands
Exit status: 0 every figure agrees, 1 a figure differs, a command failed or the doc's words or
command were not found (each named with the doc and line), 2 usage.
"""
import argparse
import json
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[2]

# ---- the runs: commands as the docs show them ------------------------------------------------


class Run:
    def __init__(self, name, doc, commands, slow=False, netns=False, retry_on=None, needs=None,
                 any_status=False, note=""):
        self.name, self.doc, self.commands = name, doc, commands
        self.any_status = any_status  # a command's status is a figure (the doc shows `echo $?`)
        self.needs = needs  # a run whose files these commands read (run first, in the same place)
        self.slow, self.netns, self.note = slow, netns, note
        # A failure whose output says this is the machine's (a deadline missed on a loaded host):
        # the run is tried again, up to 3 times.
        self.retry_on = retry_on
        self.outputs = []  # stdout of each command

    def out(self, i=-1):
        return self.outputs[i]


D = "D=tests/data/ipa-robot-accuracy"
RUNS = [
    Run("paper", "README.md", [
        "build/bin/stepcal simulate --robot irb4400 --protocol paper --seed 1 --out out/camp",
        "build/bin/stepcal calibrate out/camp --out out/model.stepcal",
        "build/bin/stepcal export urdf out/model.stepcal --out out/robot_calibrated.urdf",
    ]),
    Run("correct500", "docs/runtime.md", [
        "build/bin/stepcal demo --out out/demo",
        "build/bin/stepcal simulate --seed 5 --out out/olp",
        """awk -F, 'NR == 1 { print "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,payload_kg,cog_x_mm,cog_y_mm,cog_z_mm,cog_frame"; next }
  NR <= 501 { print $2 "," $5 "," $6 "," $7 "," $8 "," $9 "," $10 "," $4 ",30,-20,195,flange" }' \\
  out/olp/measurements.csv > out/program.csv""",
        "build/bin/stepcal correct out/demo/model.stepcal out/program.csv --out out/corrected.csv --truth out/demo/truth.json",
    ]),
    Run("programs", "docs/runtime.md", [
        "build/bin/stepcal demo --out out/demo",
        "build/bin/stepcal correct out/demo/model.stepcal tests/data/programs/twin/twin.src --out out/twin.src --truth out/demo/truth.json",
        "build/bin/stepcal correct out/demo/model.stepcal tests/data/programs/twin/twin.mod --out out/twin.mod --truth out/demo/truth.json",
        "build/bin/stepcal correct out/demo/model.stepcal tests/data/programs/twin/twin.script --out out/twin.script --truth out/demo/truth.json",
        "build/bin/stepcal correct out/demo/model.stepcal tests/data/programs/twin/twin.ls --out out/twin.ls --program-frame 'UF 1=900,-250,400,0.984807753,0,0,0.173648178' --program-frame 'UT 1=20,0,300,0.996194698,0,0.087155743,0' --truth out/demo/truth.json",
        "build/bin/stepcal correct out/demo/model.stepcal tests/data/programs/twin/twin.dat --out out/twin.dat --program-frame 'TOOL=20,0,300,0.996194698,0,0.087155743,0' --program-frame 'BASE=900,-250,400,0.984807753,0,0,0.173648178'",
    ]),
    Run("program_loads", "docs/runtime.md", [
        "build/bin/stepcal demo --out out/demo",
        "build/bin/stepcal correct out/demo/model.stepcal tests/data/programs/twin/loaded.src --out out/loaded.src --program-load 'LOAD_DATA[1]=60,10,0,200' --truth out/demo/truth.json",
    ]),
    Run("daemon", "docs/runtime.md", [
        "build/bin/stepcal demo --out out/demo",
        "build/bin/stepcal-runtime --model out/demo/model.stepcal --budget-us 1000 &",
        'T="--frame user --user-frame 1500 -200 300 0.9689124 0 0 0.2474040 --tool 0 0 350 1 0 0 0 --tool-from flange --payload 30 --cog 0 0 300 --cog-frame flange"',
        "build/bin/stepcal-client --forward 5.729578 -17.188734 22.918312 0 45.836624 0 $T",
        "build/bin/stepcal-client --inverse -178.227 452.234 896.796 0.321962 0.188062 0.925572 -0.065495 --seed 5.729578 -17.188734 22.918312 0 45.836624 0 $T",
    ], netns=True, retry_on="NOT_CONVERGED",
        note="the daemon over LCM in a private network namespace (tests/system/in_netns.sh, needs root)"),
    Run("plan60", "README.md", [
        "build/bin/stepcal plan --robot robots/irb4400.urdf --poses 60 --loads 0,20,40 --tracker 4,0,1.2 --out out/poses.csv",
        "build/bin/stepcal simulate --robot irb4400 --poses out/poses.csv --seed 1 --out out/planned",
        "build/bin/stepcal calibrate out/planned --out out/planned.stepcal --report out/planned-report.html",
    ]),
    Run("ur10_walk", "README.md", [
        "build/bin/stepcal plan --robot robots/ur10.urdf --poses 40 --out out/ur10-poses.csv",
        "build/bin/stepcal simulate --robot robots/ur10.urdf --poses out/ur10-poses.csv --seed 1 --out out/ur10-twin",
        "build/bin/stepcal calibrate out/ur10-twin --out out/ur10-twin.stepcal",
        "build/bin/stepcal diagnose out/ur10-twin --out out/ur10-twin.extended.stepcal",
    ]),
    Run("ur10_C", "README.md", [
        D,
        "build/bin/stepcal import ipa $D/Series_C/measurements_random_poses.csv --validation-from-row 2000 --out out/ur10-C",
        "build/bin/stepcal calibrate out/ur10-C --json   # rms and the GPR columns",
        "build/bin/stepcal import ipa $D/Series_B/measurements_joint_configurations.csv --out out/ur10-B",
        "build/bin/stepcal import ipa $D/Series_C/measurements_random_poses.csv --validation-from-row 0 --out out/ur10-C-all",
        "build/bin/stepcal calibrate out/ur10-B --out out/ur10-B.stepcal",
        # the doc's `validate … [--refit-frames]`: without, then with
        "build/bin/stepcal validate out/ur10-B.stepcal out/ur10-C-all --json",
        "build/bin/stepcal validate out/ur10-B.stepcal out/ur10-C-all --refit-frames --json",
    ]),
    Run("hidden", "docs/diagnosis.md", [
        """build/bin/stepcal simulate --seed 3 --effect '{"name": "backlash", "joint": 2, "lost_motion_rad": 2e-4}' --out out/hidden-3""",
        "build/bin/stepcal diagnose out/hidden-3 --json",
        """build/bin/stepcal simulate --seed 4 --effect '{"name": "transmission_error", "joint": 3, "harmonic": 2, "sin_rad": 1e-4, "cos_rad": -5e-5}' --out out/hidden-4""",
        "build/bin/stepcal diagnose out/hidden-4 --json",
        """build/bin/stepcal simulate --seed 5 --effect '{"name": "nonlinear_stiffness", "joint": 3, "extra_compliance_rad_per_nm": 1e-6, "saturation_torque_nm": 200}' --out out/hidden-5""",
        "build/bin/stepcal diagnose out/hidden-5 --json",
        """build/bin/stepcal simulate --seed 6 --effect '{"name": "joint_coupling", "joints": [5, 6], "ratio": 1e-3}' --out out/hidden-6""",
        "build/bin/stepcal diagnose out/hidden-6 --json",
        "build/bin/stepcal simulate --seed 1 --out out/hidden-none",
        "build/bin/stepcal diagnose out/hidden-none --json",
    ]),
    Run("plan_compare_random", "README.md", [
        "$ build/bin/stepcal-plan-compare --planned random --poses 10,60",
        "$ echo $?",
    ], slow=True, any_status=True),
    Run("counts", "README.md", ["ctest --test-dir build -N -L unit"],
        note="the GoogleTest cases, once tools/test.sh has built every one of them"),
    Run("ur10_C_diagnose", "README.md", [  # the doc's diagnose command of "The twin of a calibrated robot"
        D,
        "build/bin/stepcal import ipa $D/Series_C/measurements_random_poses.csv --validation-from-row 2000 --out out/ur10-C",
        "build/bin/stepcal diagnose out/ur10-C --out out/ur10-C.extended.stepcal",
        "build/bin/stepcal validate out/ur10-C.extended.stepcal out/ur10-C --json   # the same held-out error, from the model file",
    ], slow=True),
    Run("ur10_C_twin", "docs/diagnosis.md", [
        "build/bin/stepcal simulate --model out/ur10-C.extended.stepcal --seed 1 --out out/ur10-C-twin",
        "build/bin/stepcal calibrate out/ur10-C-twin",  # the doc's comment holds the figures
        "build/bin/stepcal calibrate out/ur10-C",
    ], slow=True, needs="ur10_C_diagnose"),
    Run("iso9283", "docs/certify.md", [
        "build/bin/stepcal plan --robot irb4400 --iso9283 --rated-load-kg 60 --out out/iso-irb4400.csv",
        "build/bin/stepcal plan --robot ur10 --iso9283 --out out/iso-ur10.csv",
        "build/bin/stepcal simulate --robot irb4400 --seed 1 --out out/camp",
        "build/bin/stepcal calibrate out/camp --out out/model.stepcal",
        "build/bin/stepcal simulate --robot irb4400 --seed 1 --poses out/iso-irb4400.csv --out out/iso-camp",
        "build/bin/stepcal certify out/model.stepcal out/iso-camp --html out/certificate.html",
    ]),
    Run("iso9283_ur10", "docs/certify.md", [
        D,
        "build/bin/stepcal import ipa $D/Series_A/measurements_grid.csv --out out/ur10-A",
        "build/bin/stepcal import ipa $D/Series_D/measurements_iso_cubes.csv --out out/ur10-D",
        "build/bin/stepcal import ipa $D/Series_B/measurements_joint_configurations.csv --out out/ur10-B",
        "build/bin/stepcal calibrate out/ur10-A --out out/ur10-A.stepcal",
        "build/bin/stepcal certify out/ur10-A.stepcal out/ur10-D --refit-frames",
        "build/bin/stepcal certify out/ur10-A.stepcal out/ur10-B --refit-frames",
    ]),
    Run("iso9283_readme", "README.md", [
        "build/bin/stepcal plan --robot irb4400 --iso9283 --rated-load-kg 60 --out out/iso-irb4400.csv",
        "build/bin/stepcal simulate --robot irb4400 --seed 1 --poses out/iso-irb4400.csv --out out/iso-camp",
        "build/bin/stepcal certify out/model.stepcal out/iso-camp --html out/certificate.html",
    ], needs="paper"),
    Run("ur10_series", "README.md", [
        "tools/ur10_series.sh                            # the across-series table (needs jq)",
    ], slow=True),
]
RUN = {r.name: r for r in RUNS}
# Commands that show a doc's optional flag expanded: the doc's line with the flag in brackets.
EXPANDED = {
    "build/bin/stepcal validate out/ur10-B.stepcal out/ur10-C-all --json":
        "build/bin/stepcal validate out/ur10-B.stepcal out/ur10-C-all [--refit-frames]",
    "build/bin/stepcal validate out/ur10-B.stepcal out/ur10-C-all --refit-frames --json":
        "build/bin/stepcal validate out/ur10-B.stepcal out/ur10-C-all [--refit-frames]",
}

# ---- reading the commands' output ------------------------------------------------------------


def accuracy_table(text, set_name, load_kg, method):
    """(mean, max, orientation) of a method in calibrate's or validate's accuracy table, as printed."""
    lines = text.splitlines()
    for i, line in enumerate(lines):
        if not line.startswith("set ") or "load_kg" not in line:
            continue
        methods = re.split(r"\s{2,}", line.strip())[3:]
        for row in lines[i + 1:]:
            cells = row.split()
            if len(cells) < 3 or not re.fullmatch(r"[\d.]+", cells[1]):
                break
            if cells[0] == set_name and float(cells[1]) == load_kg:
                groups = [cells[3 + 4 * k: 7 + 4 * k] for k in range(len(methods))]
                return dict(zip(methods, ((g[0], g[2], g[3]) for g in groups)))[method]
    raise LookupError(f"no {set_name} {load_kg} kg {method} in the accuracy table")


def validation(rows, method, load_kg=0.0, set_name="validation"):
    """A row of calibrate --json's `validation` or validate --json's list."""
    rows = rows["validation"] if isinstance(rows, dict) else rows
    for r in rows:
        if r["method"] == method and r["load_kg"] == load_kg and r.get("set", set_name) == set_name:
            return r
    raise LookupError(f"no {method} at {load_kg} kg ({set_name})")


def grep(pattern, text, group=1):
    m = re.search(pattern, text)
    if m is None:
        raise LookupError(f"'{pattern}' not in the output")
    return m.group(group)


def grep_all(pattern, text):
    found = re.findall(pattern, text)
    if not found:
        raise LookupError(f"'{pattern}' not in the output")
    return found


def vector(label, text):
    """The numbers of a client's line `label [a, b, c]`, as printed."""
    return [v.strip() for v in grep(label + r"\s+\[([^\]]*)\]", text).split(",")]


def out(run, i=-1):
    return RUN[run].out(i)


def js(run, i=-1):
    return json.loads(RUN[run].out(i))


def series_mean(name, method, set_name=""):
    """Mean position error (mm) of a method in one of tools/ur10_series.sh's validate JSONs."""
    for r in series_json(name):
        if r["method"] == method and (not set_name or r.get("set") == set_name):
            return r["mean_position_mm"]
    raise LookupError(f"no {method} in {name}")


def truth_stiffness(campaign):
    """The joint stiffnesses (N·m/rad) a twin campaign's truth.json holds."""
    truth = json.loads((WORK / campaign / "truth.json").read_text())
    return next(e for e in truth["effects"] if e["name"] == "joint_compliance")["stiffness_nm_per_rad"]


def series_json(name):
    return json.loads((WORK / "out/ur10-series" / name).read_text())


def series_drift(series):
    """The registration drift the diagnosis of a series names (tools/ur10_series.sh's JSON)."""
    return next(e for e in series_json(f"{series}.diagnosis.json")["effects"]
                if e["name"] == "registration_drift")


def series_table():
    """tools/ur10_series.sh's table as printed: rows of cells by the case's first word."""
    table = {}
    for line in (WORK / "out/ur10-series/table.md").read_text().splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if "→" in cells[0]:
            table[cells[0].split()[0]] = cells[1:]
    return table


def diag_gain(text):
    """The diagnosis's gain row at 0 kg: before, after, poe+gpr, extended+gpr (mean, max, deg)."""
    cells, groups = grep(r"\n\s+0 kg\s+\d+\s+([\d. -]+)\n", text).split(), []
    while cells:  # "-": a column without a model (no GPR)
        take = 1 if cells[0] == "-" else 3
        groups.append(cells[:take])
        cells = cells[take:]
    return groups


def effect(i):
    """The first effect a diagnosis of the hidden run names (its command i's JSON)."""
    return js("hidden", i)["effects"][0]


def harmonic(i, k):
    return next(h for h in effect(i)["harmonics"] if h["harmonic"] == k)


def gain55(i):
    """Before, after and poe+stiffness+gpr at 55 kg: the mean position error, mm."""
    row = lambda: next(g for g in js("hidden", i)["gain"] if g["load_kg"] == 55.0)
    return (lambda: row()["before_mean_position_mm"], lambda: row()["after_mean_position_mm"],
            lambda: row()["gpr_mean_position_mm"])


# stepcal plan: "from 653 visible of 2000 candidates (0 out of range, 1219 below the floor, 128 …"
PLAN_KEPT = r"from (\d+) visible of (\d+) candidates \(\d+ out of range, (\d+) below the floor, (\d+)"


# ---- the figures -----------------------------------------------------------------------------
# Fig(doc, words, run, value, …): in doc, the words with {} for each figure; per figure a function
# of no argument giving the code's value (a string as printed, or a float at full precision).


def iso_figure(run, i, load, method, label):
    """A figure of `stepcal certify`'s text: at a load, the method's (0 commanded, 1 corrected)
    line `label … N mm`."""
    section = out(run, i).split(f"load {load} kg:")[1].split("\nload ")[0]
    block = re.split(r"\n  (?=\S)", section)[1 + method]
    return grep(re.escape(label) + r"\s+(-?[\d.]+) mm", block)


def iso_plan_cube(i, k):
    """The plan's cube: edge, then the centre's x, y, z (mm)."""
    return grep(r"cube: edge ([\d.]+) mm.*centre \((-?[\d.]+), (-?[\d.]+), (-?[\d.]+)\) mm",
                out("iso9283", i), k)


def iso_twin_row(load):
    ap, rp, ad = "AP_P (largest over the poses)", "RP_l (cycles pooled)", "AD_P (P2–P4, 30 cycles)"
    return Fig("docs/certify.md", f"| {load} kg | {{}} mm | {{}} mm | {{}} mm | {{}} / {{}} mm |", "iso9283",
               lambda: iso_figure("iso9283", 5, load, 0, ap), lambda: iso_figure("iso9283", 5, load, 1, ap),
               lambda: iso_figure("iso9283", 5, load, 0, rp), lambda: iso_figure("iso9283", 5, load, 0, ad),
               lambda: iso_figure("iso9283", 5, load, 1, ad))


def iso_ur10_row(series, i):
    ap_med, ap_max = "AP_P (median of the poses)", "AP_P (largest over the poses)"
    rp_med, rp_pool = "RP_l (median of the poses)", "RP_l (cycles pooled)"
    f = lambda m, label: (lambda: iso_figure("iso9283_ur10", i, 0, m, label))
    return Fig("docs/certify.md", f"| {series} | {{}} ({{}}) | {{}} / {{}} mm | {{}} / {{}} mm | {{}} / {{}} mm |",
               "iso9283_ur10",
               lambda: grep(r"\((\d+) poses: per pose", out("iso9283_ur10", i)),
               lambda: grep(r"(\d+) poses measured more than once", out("iso9283_ur10", i)),
               f(0, ap_med), f(0, ap_max), f(1, ap_med), f(1, ap_max), f(0, rp_med), f(0, rp_pool))


class Fig:
    def __init__(self, doc, words, run, *values):
        self.doc, self.words, self.run, self.values = doc, words, run, values


def paper_row(load, rows):
    """The README's paper table row at a load: nominal, poe, poe+stiffness, poe+gpr, poe+stiffness+gpr."""
    calib = lambda m, k: (lambda: accuracy_table(out("paper", 1), "validation", load, m)[k])
    values = []
    for m in ("nominal", "poe", "poe+stiffness", "poe+gpr", "poe+stiffness+gpr"):
        values += [calib(m, 0), calib(m, 2)]
    label = f"| {int(load)} kg ({rows}) |"
    return Fig("README.md", label + " {} / {} |" * 5, "paper", *values)


def urdf_row(load, first):
    calib = lambda m, k: (lambda: accuracy_table(out("paper", 1), "validation", load, m)[k])
    label = "| simulated IRB4400, paper protocol, seed 1 (`poe+stiffness+gpr`) | 0 kg |" if first \
        else f"| | {int(load)} kg |"
    return Fig("README.md", label + " {} / {} | {} / {} |", "paper", calib("poe", 0), calib("poe", 2),
               calib("poe+stiffness+gpr", 0), calib("poe+stiffness+gpr", 2))


def stiffness(joint, k):
    return lambda: grep(rf"\n  joint_{joint}\s+(\d+)\s+(\d+)", out("paper", 1), k)


def series_row(doc, label, key):
    cell = lambda i: (lambda: series_table()[key][i])
    return Fig(doc, label + " | {} | {} | {} | - | {} | {} | {} |", "ur10_series",
               *(cell(i) for i in (0, 1, 2, 4, 5, 6)))


def drift_row(label, case):
    """docs/diagnosis.md's drift table: the 'now' columns, from the series' JSONs (the 'before'
    columns are an older build's)."""
    src, tgt = case.split(":")
    same = src == tgt
    suffix = "" if same else " (frames refit)"
    set_name = "validation" if same else ""
    name = f"{src}-{tgt}.extended.json"
    return Fig("docs/diagnosis.md", label + " | {-} | {} | {-} | {} |",
               "ur10_series",
               lambda: series_mean(name, "extended" + suffix, set_name),
               lambda: series_mean(name, f"extended{suffix} (covered rows)", set_name))


FIGS = [
    # README, Results: the simulated IRB4400 (tools/quickstart.sh's campaign, seed 1)
    Fig("README.md", "the noise floor (mean error the noise alone gives) is\n{} mm and {}°", "paper",
        lambda: grep(r"noise floor \(mean\) ([\d.]+) mm", out("paper", 1)),
        lambda: grep(r"noise floor \(mean\) [\d.]+ mm, ([\d.]+) deg", out("paper", 1))),
    Fig("README.md", "Step 1 fits the {} geometry\nrows, converges in {} iterations, rank {} of {}", "paper",
        lambda: grep(r"geometry \(local POE\): (\d+) rows", out("paper", 1)),
        lambda: grep(r"converged after (\d+) iterations", out("paper", 1)),
        lambda: grep(r"rank (\d+) of", out("paper", 1)),
        lambda: grep(r"rank \d+ of (\d+)", out("paper", 1))),
    paper_row(0.0, "80 rows"), paper_row(20.0, "80"), paper_row(30.0, "80"), paper_row(40.0, "80"),
    paper_row(55.0, "50, extrapolation"),
    Fig("README.md", "| identified | not excited | {} ± {} | {} ± {} | {} ± {} | {} ± {} | {} ± {} |", "paper",
        *(stiffness(j, k) for j in range(2, 7) for k in (1, 2))),
    Fig("README.md", "deflection on the validation pairs: {} / {} / {} % mean deviation at 20 / 30 / 40 kg", "paper",
        *(lambda load=load: grep(rf"{load}.0 kg:.*deviation mean ([\d.]+) %", out("paper", 1))
          for load in (20, 30, 40))),
    Fig("README.md", "deflects the tip\n{} / {} / {} mm on average at 20 / 30 / 40 kg", "paper",
        *(lambda load=load: grep(rf"{load}.0 kg:.*deflection ([\d.]+) mm", out("paper", 1))
          for load in (20, 30, 40))),
    Fig("README.md", "(here at the noise floor, ≤ {}× at every load)", "paper",
        lambda: max(float(accuracy_table(out("paper", 1), "validation", load, m)[0])
                    for load in (0.0, 20.0, 30.0, 40.0, 55.0) for m in ("poe+stiffness", "poe+stiffness+gpr")) /
        float(grep(r"noise floor \(mean\) ([\d.]+) mm", out("paper", 1)))),
    Fig("README.md", "{} kB for the paper's campaign", "paper",
        lambda: (WORK / "out/model.stepcal").stat().st_size / 1000),
    urdf_row(0.0, True), urdf_row(20.0, False), urdf_row(40.0, False), urdf_row(55.0, False),
    Fig("README.md", "| real UR10 Series C, 773 held-out rows (`poe+gpr`) | 0 kg | {} / {} | {} / {} |", "ur10_C",
        *(lambda m=m, k=k: validation(js("ur10_C", 2), m)[k]
          for m in ("poe", "poe+gpr") for k in ("mean_position_mm", "mean_orientation_deg"))),
    Fig("README.md", "runs the GoogleTest cases labelled `unit` ({} cases:", "counts",
        lambda: grep(r"Total Tests: (\d+)", out("counts"))),
    # docs/diagnosis.md and README: one hidden mechanism each on the simulated IRB4400
    Fig("docs/diagnosis.md", "| backlash joint 2, b = 2.0e-4 rad (3) | backlash (joint 2), b = {} ± {} | {} | {} | {} |",
        "hidden", lambda: effect(1)["parameters"]["lost_motion_rad"],
        lambda: effect(1)["uncertainty"]["lost_motion_rad"], *gain55(1)),
    Fig("README.md", "(b = 2.0e-4 rad, seed 3) as {} ± {} rad, {} → {} mm at 55 kg where\n`poe+stiffness+gpr` gets {} mm",
        "hidden", lambda: effect(1)["parameters"]["lost_motion_rad"],
        lambda: effect(1)["uncertainty"]["lost_motion_rad"], *gain55(1)),
    Fig("README.md", "poe+stiffness on the loaded validation rows goes from {-}–{-} mm to {}–{} mm and "
        "poe+stiffness+gpr recovers only part of it ({}–{} mm)", "hidden",
        *(lambda f=f, k=k: f(g[k] for g in js("hidden", 1)["gain"] if g["load_kg"] > 0)
          for k in ("before_mean_position_mm", "gpr_mean_position_mm") for f in (min, max))),
    Fig("docs/diagnosis.md", "| profile of joint 3, {} harmonics: h2 ({} ± {}, {} ± {})e-4 ({} % of h2 within reach of "
        "the geometry on this {}° arc) | {} | {} | {} |", "hidden",
        lambda: effect(3)["order"],
        *(lambda k=k: 1e4 * harmonic(3, 2)[k] for k in ("sin_rad", "sin_sigma_rad", "cos_rad", "cos_sigma_rad")),
        lambda: 100 * harmonic(3, 2)["geometry_share"],
        lambda: sum(b - a for a, b in effect(3)["coverage_deg"]), *gain55(3)),
    Fig("docs/diagnosis.md", "| c = {} ± {}, τ₀ = {} ± {} | {} | {} | {} |", "hidden",
        lambda: effect(5)["parameters"]["extra_compliance_rad_per_nm"],
        lambda: effect(5)["uncertainty"]["extra_compliance_rad_per_nm"],
        lambda: effect(5)["parameters"]["saturation_torque_nm"],
        lambda: effect(5)["uncertainty"]["saturation_torque_nm"], *gain55(5)),
    Fig("docs/diagnosis.md", "| joint_coupling 5 → 6, 1e-3 (6) | {} ± {} | {} | {} | {} |", "hidden",
        lambda: effect(7)["parameters"]["ratio"], lambda: effect(7)["uncertainty"]["ratio"], *gain55(7)),
    Fig("docs/diagnosis.md", "| none (1) | verdict `none` | {} (0 kg) | | |", "hidden",
        lambda: js("hidden", 9)["gain"][0]["before_mean_position_mm"] if js("hidden", 9)["verdict"] == "none"
        else f"verdict {js('hidden', 9)['verdict']}"),
    # docs/runtime.md: 500 targets of an offline program corrected
    Fig("docs/runtime.md", "wrote out/corrected.csv: {} lines: {} OK, {} OUT_OF_DOMAIN, {} UNREACHABLE, "
        "{} NOT_CONVERGED, {} NEAR_SINGULAR, {} BAD_REQUEST; {} in the model's coverage", "correct500",
        *(lambda i=i: grep_all(r"\d+", grep(r"(wrote out/corrected.csv: .*)", out("correct500")))[i]
          for i in range(8))),
    Fig("docs/runtime.md", "BAD_REQUEST; {-} in the model's coverage on the twin, as commanded: mean {} mm, "
        "max {} mm, mean {} deg over {} targets", "correct500",
        *(lambda i=i: grep(r"as commanded: mean ([\d.]+) mm, max ([\d.]+) mm, mean ([\d.]+) deg over (\d+)",
                           out("correct500"), i) for i in range(1, 5))),
    Fig("docs/runtime.md", "BAD_REQUEST; {-} in the model's coverage on the twin, as commanded: mean {-} mm, "
        "max {-} mm, mean {-} deg over {-} targets on the twin, as corrected: mean {} mm, max {} mm, mean {} deg "
        "over {} targets", "correct500",
        *(lambda i=i: grep(r"as corrected: mean ([\d.]+) mm, max ([\d.]+) mm, mean ([\d.]+) deg over (\d+)",
                           out("correct500"), i) for i in range(1, 5))),
    # docs/runtime.md: the robot's own programs (the KRL run; the others print the same figures)
    Fig("docs/runtime.md", "twin.src:7:5: joints: corrected (moved {} mm, {} deg)", "programs",
        *(lambda i=i: grep(r"twin.src:7:5: joints: corrected \(moved ([\d.]+) mm, ([\d.]+) deg", out("programs", 1), i)
          for i in (1, 2))),
    Fig("docs/runtime.md", "twin.src:8:5: pose: corrected (moved {} mm, {} deg)", "programs",
        *(lambda i=i: grep(r"twin.src:8:5: pose: corrected \(moved ([\d.]+) mm, ([\d.]+) deg", out("programs", 1), i)
          for i in (1, 2))),
    Fig("docs/runtime.md", "wrote out/twin.src (KUKA KRL): {} targets: {} corrected; {} not a literal; {} in the model's "
        "coverage", "programs",
        *(lambda i=i: grep(r"wrote out/twin.src \(KUKA KRL\): (\d+) targets: (\d+) corrected; (\d+) not a literal; "
                           r"(\d+) in the model's coverage", out("programs", 1), i) for i in range(1, 5))),
    *(Fig("docs/runtime.md", "out/twin.src (KUKA KRL): {-} targets: {-} corrected; {-} not a literal; {-} in the model's coverage "
          "on the twin, as " + kind + ": mean {} mm, "
          "max {} mm, mean {} deg over {} targets", "programs",
          *(lambda i=i, kind=kind, run=run: grep(r"as " + kind + r": mean ([\d.]+) mm, max ([\d.]+) mm, mean ([\d.]+) "
                                                 r"deg over (\d+)", out("programs", run), i) for i in range(1, 5)))
      for kind in ("commanded",) for run in (1, 2, 3, 4)),
    *(Fig("docs/runtime.md", "over {-} targets on the twin, as corrected: mean {} mm, max {} mm, mean {} deg over {} "
          "targets ``` The corrected", "programs",
          *(lambda i=i, run=run: grep(r"as corrected: mean ([\d.]+) mm, max ([\d.]+) mm, mean ([\d.]+) deg over (\d+)",
                                      out("programs", run), i) for i in range(1, 5)))
      for run in (1, 2, 3, 4)),
    # docs/runtime.md: a program's load
    *(Fig("docs/runtime.md", "loaded.src:" + at + ": joints: corrected (moved {} mm, {} deg); load " + load + ": {} kg at "
          "{} {} {} mm in the flange", "program_loads",
          *(lambda i=i, at=at: grep(re.escape("loaded.src:" + at) + r": joints: corrected \(moved ([\d.]+) mm, ([\d.]+) deg\); "
                                    r"load .*: ([\d.]+) kg at ([-\d.]+) ([-\d.]+) ([-\d.]+) mm", out("program_loads", 1), i)
            for i in range(1, 7)))
      for at, load in (("4:5", "$LOAD line 3"), ("8:5", "LOAD_DATA[1]"))),
    Fig("docs/runtime.md", "wrote out/loaded.src (KUKA KRL): {} targets: {} corrected; {} not a literal; {} in the model's "
        "coverage on the twin, as commanded: mean {} mm, max {} mm, mean {} deg over {} targets on the twin, as corrected: "
        "mean {} mm, max {} mm, mean {} deg over {} targets", "program_loads",
        *(lambda i=i: grep_all(r"\d+(?:\.\d+)?", grep(r"(wrote out/loaded.src .*)", out("program_loads", 1)))[i]
          for i in range(4)),
        *(lambda i=i, kind=kind: grep(r"as " + kind + r": mean ([\d.]+) mm, max ([\d.]+) mm, mean ([\d.]+) deg over (\d+)",
                                      out("program_loads", 1), i) for kind in ("commanded", "corrected") for i in range(1, 5))),
    Fig("docs/runtime.md", "The corrected {} mm is the model's own error at a tool given from the flange", "programs",
        lambda: grep(r"as corrected: mean ([\d.]+) mm", out("programs", 1))),
    Fig("docs/runtime.md", "The corrected error, {} mm, is the model's own", "correct500",
        lambda: grep(r"as corrected: mean ([\d.]+) mm", out("correct500"))),
    Fig("README.md", "(on the twin: {} joint targets from {} mm to {} mm mean)", "correct500",
        lambda: grep(r"as corrected: .* over (\d+)", out("correct500")),
        lambda: grep(r"as commanded: mean ([\d.]+) mm", out("correct500")),
        lambda: grep(r"as corrected: mean ([\d.]+) mm", out("correct500"))),
    # docs/runtime.md: the worked example through the daemon
    Fig("docs/runtime.md", "The forward answer: the real TCP at ({}, {}, {}) m in the fixture's frame,\n"
        "under the payload's wrench ({}, {}, {}) N on the sensor", "daemon",
        *(lambda i=i: vector(r"predicted \(user\s*\) p_m", out("daemon", 3))[i] for i in range(3)),
        *(lambda i=i: vector(r"wrench used \(N, N m\)", out("daemon", 3))[i] for i in range(3))),
    Fig("docs/runtime.md", "OK after {} steps, q_target ({}, {}, {},\n{}, {}, {})°", "daemon",
        lambda: grep(r"iterations (\d+)", out("daemon", 4)),
        *(lambda i=i: vector(r"q_target_deg", out("daemon", 4))[i] for i in range(6))),
    Fig("docs/runtime.md", "the pre-distorted pose for a controller that takes poses:\n({}, {}, {}) m", "daemon",
        *(lambda i=i: vector(r"commanded \(user\s*\) p_m", out("daemon", 4))[i] for i in range(3))),
    # README, Planned against random poses: the documented failing run, line by line
    Fig("README.md", "$ build/bin/stepcal-plan-compare --planned random --poses 10,60\n"
        "| 10 | {} / {} | {} / {} | {} / {} |\n| 60 | {} / {} | {} / {} | {} / {} |\n"
        "goal met: random reaches the paper protocol's {} mm at N = {} <= {} / 2\n"
        "at N = 10, random / random (paper's ranges) against the truth: {} (FAILED: not below 0.80)\n"
        "at N = 10, random / random (joint limits) against the truth: {} (FAILED: not below 0.80)\n"
        "$ echo $?\n{}", "plan_compare_random",
        *(lambda n=n, i=i: grep_all(r"[\d.]+", grep(rf"\n?(\| {n} \|[^\n]*)", out("plan_compare_random", 0)))[i]
          for n in (10, 60) for i in range(1, 7)),
        *(lambda i=i: grep(r"reaches the paper protocol's ([\d.]+) mm at N = (\d+) <= (\d+)",
                           out("plan_compare_random", 0), i) for i in (1, 2, 3)),
        lambda: grep(r"\(paper's ranges\) against the truth: ([\d.]+)", out("plan_compare_random", 0)),
        lambda: grep(r"\(joint limits\) against the truth: ([\d.]+)", out("plan_compare_random", 0)),
        lambda: out("plan_compare_random", 1).strip()),
    # README, From plan to URDF
    Fig("README.md", "how many candidates it kept (here {} of {}:\n{} with a link below the floor, {} with the arm in the line of sight)",
        "plan60", *(lambda i=i: grep(PLAN_KEPT,
                                     out("plan60", 0), i) for i in range(1, 5))),
    Fig("README.md", "(the 60-pose plan\ncovers all {} bins of every joint)", "plan60",
        lambda: str(round(8 * min(float(v) for v in grep_all(r"q\d ([\d.]+)", grep(r"(joint range covered.*)",
                                                                                  out("plan60", 0))))))),
    Fig("README.md", "writes the campaign ({} geometry, {} stiffness and {} validation rows)", "plan60",
        *(lambda s=s: grep(rf"(\d+) {s}", out("plan60", 2)) for s in ("geometry", "stiffness", "validation"))),
    Fig("README.md", "(poe+stiffness on the validation rows: {}–{} mm per load", "plan60",
        lambda: min((accuracy_table(out("plan60", 2), "validation", l, "poe+stiffness")[0]
                     for l in (0.0, 20.0, 30.0, 40.0, 55.0)), key=float),
        lambda: max((accuracy_table(out("plan60", 2), "validation", l, "poe+stiffness")[0]
                     for l in (0.0, 20.0, 30.0, 40.0, 55.0)), key=float)),
    # README, Your own robot: the walk on the UR10
    Fig("README.md", "`plan` keeps {} of {} candidates ({} with a link below the floor, {} with the arm in the\nline of sight)",
        "ur10_walk", *(lambda i=i: grep(PLAN_KEPT,
                                        out("ur10_walk", 0), i) for i in range(1, 5))),
    Fig("README.md", "covers every joint's range but q2's ({} of it:", "ur10_walk",
        lambda: grep(r"joint range covered.* q2 ([\d.]+)", out("ur10_walk", 0))),
    Fig("README.md", "on the {} validation rows the geometric model\n(`calibrate`'s `poe`) leaves {} mm", "ur10_walk",
        lambda: grep(r"validation\s+0\.0\s+(\d+)", out("ur10_walk", 2)),
        lambda: accuracy_table(out("ur10_walk", 2), "validation", 0.0, "poe")[0]),
    Fig("README.md", "compliance {} and {} rad/(N·m); truth {} and {})", "ur10_walk",
        lambda: grep(r"joint 2 compliance ([\d.e+-]+)", out("ur10_walk", 3)),
        lambda: grep(r"joint 3 compliance ([\d.e+-]+)", out("ur10_walk", 3)),
        *(lambda j=j: 1.0 / truth_stiffness("out/ur10-twin")[j] for j in (1, 2))),
    Fig("README.md", "and its extended model\nreaches {} mm, the noise floor ({} mm)", "ur10_walk",
        lambda: diag_gain(out("ur10_walk", 3))[1][0],
        lambda: grep(r"noise floor ([\d.]+) mm", out("ur10_walk", 3))),
    # README, Real UR10 data
    Fig("README.md", "| Series C: fit on the first 2000 rows, check the other 773 | {} held out | {} / {} / {}, {}° | "
        "**{} / {} / {}, {}°** | **{} / {} / {}, {}°** |", "ur10_C",
        lambda: validation(js("ur10_C", 2), "poe")["rows"],
        *(lambda m=m, k=k: validation(js("ur10_C", 2), m)[k]
          for m in ("frames", "poe", "poe+gpr")
          for k in ("mean_position_mm", "rms_position_mm", "max_position_mm", "mean_orientation_deg"))),
    Fig("README.md", "| fit on Series B, check on all 2773 rows of Series C | {} | — | {} / {} / {}, {}° | {} / {} / {}, {}° |",
        "ur10_C", lambda: validation(js("ur10_C", 6), "poe")["rows"],
        *(lambda m=m, k=k: validation(js("ur10_C", 6), m)[k]
          for m in ("poe", "poe+gpr")
          for k in ("mean_position_mm", "rms_position_mm", "max_position_mm", "mean_orientation_deg"))),
    Fig("README.md", "| the same, tracker and tool frames refit on C (`--refit-frames`) | {} | — | {} / {} / {}, {}° | {} / {} / {}, {}° |",
        "ur10_C", lambda: validation(js("ur10_C", 7), "poe (frames refit)")["rows"],
        *(lambda m=m, k=k: validation(js("ur10_C", 7), m)[k]
          for m in ("poe (frames refit)", "poe+gpr (frames refit)")
          for k in ("mean_position_mm", "rms_position_mm", "max_position_mm", "mean_orientation_deg"))),
    Fig("README.md", "| Series B: fit on all 1495 rows (fit error) | {} | {} / {-} / {}, {}° | {} / {-} / {}, {}° | |",
        "ur10_C", lambda: grep(r"\ngeometry\s+0\.0\s+(\d+)", out("ur10_C", 5)),
        *(lambda m=m, k=k: accuracy_table(out("ur10_C", 5), "geometry", 0.0, m)[k]
          for m in ("frames", "poe") for k in range(3))),
    Fig("README.md", "is {} mm off on C's held-out\nrows", "ur10_C",
        lambda: validation(js("ur10_C", 2), "nominal")["mean_position_mm"]),
    Fig("README.md", "carry over to Series C ({} mm once the tracker and tool frames are\nregistered again); "
        "used as they are, the error is {} mm", "ur10_C",
        lambda: validation(js("ur10_C", 7), "poe (frames refit)")["mean_position_mm"],
        lambda: validation(js("ur10_C", 6), "poe")["mean_position_mm"]),
    Fig("README.md", "Within Series C the GPR removes a further {} %; trained on Series B it does not carry over to C\n"
        "({} → {} mm)", "ur10_C",
        lambda: 100 * (1 - validation(js("ur10_C", 2), "poe+gpr")["mean_position_mm"] /
                       validation(js("ur10_C", 2), "poe")["mean_position_mm"]),
        lambda: validation(js("ur10_C", 6), "poe")["mean_position_mm"],
        lambda: validation(js("ur10_C", 6), "poe+gpr")["mean_position_mm"]),
    # README and docs/diagnosis.md: the diagnosis of Series C
    Fig("README.md", "(compliance {} ± {} and\n{} ± {} rad/(N·m), identified from self weight alone", "ur10_C_diagnose",
        *(lambda j=j, k=k: grep(rf"joint {j} compliance ([\d.e+-]+) rad/\(N·m\) ± ([\d.e+-]+)", out("ur10_C_diagnose", 2), k)
          for j in (2, 3) for k in (1, 2))),
    Fig("docs/diagnosis.md", "the compliance of the shoulder and the\n   elbow, {} ± {} and {} ± {} rad/(N·m)", "ur10_C_diagnose",
        *(lambda j=j, k=k: grep(rf"joint {j} compliance ([\d.e+-]+) rad/\(N·m\) ± ([\d.e+-]+)", out("ur10_C_diagnose", 2), k)
          for j in (2, 3) for k in (1, 2))),
    Fig("README.md", "transmission profile on every joint ({}–{} harmonics, RMS {}–{} µrad over the fit rows)", "ur10_C_diagnose",
        lambda: min(grep_all(r"round \d+, transmission_error \(joint \d, (\d+) harmonics\)", out("ur10_C_diagnose", 2)), key=int),
        lambda: max(grep_all(r"round \d+, transmission_error \(joint \d, (\d+) harmonics\)", out("ur10_C_diagnose", 2)), key=int),
        lambda: min(grep_all(r"harmonics\): RMS (\d+) urad", out("ur10_C_diagnose", 2)), key=int),
        lambda: max(grep_all(r"harmonics\): RMS (\d+) urad", out("ur10_C_diagnose", 2)), key=int)),
    Fig("docs/diagnosis.md", "joint 2 ({} harmonics, RMS {} µrad over the fit rows), joint 1 ({},\n   {} µrad), joint 3 ({}, {} µrad), "
        "joint 4 ({}, {} µrad), joint 5 ({}, {} µrad), joint 6 ({},\n   {} µrad", "ur10_C_diagnose",
        *(lambda j=j, k=k: grep(rf"round \d+, transmission_error \(joint {j}, (\d+) harmonics\): RMS (\d+) urad",
                                out("ur10_C_diagnose", 2), k)
          for j in (2, 1, 3, 4, 5, 6) for k in (1, 2))),
    Fig("docs/diagnosis.md", "harmonic 1 of each is {}–{} % within reach", "ur10_C_diagnose",
        lambda: min(grep_all(r"harmonics\): harmonic 1 (\d+) %", out("ur10_C_diagnose", 2)), key=int),
        lambda: max(grep_all(r"harmonics\): harmonic 1 (\d+) %", out("ur10_C_diagnose", 2)), key=int)),
    Fig("docs/diagnosis.md", "the refitted geometric model leaves\n{} mm mean on the fit rows ({}× the tracker's stated noise)",
        "ur10_C_diagnose",
        lambda: grep(r"before: \d+ fit rows, position error mean ([\d.]+) mm", out("ur10_C_diagnose", 2)),
        lambda: grep(r"before: .*; ([\d.]+) times the stated", out("ur10_C_diagnose", 2))),
    Fig("docs/diagnosis.md", "Held out, the mean position error goes **{} → {} mm** (−{} %; max {} → {} mm), {}× the\n"
        "tracker's noise floor ({} mm); `poe+gpr` gets {} mm (`stepcal validate` on the model it\nwrites gives the same {} mm)",
        "ur10_C_diagnose",
        lambda: diag_gain(out("ur10_C_diagnose", 2))[0][0],
        lambda: diag_gain(out("ur10_C_diagnose", 2))[1][0],
        lambda: 100 * (1 - float(diag_gain(out("ur10_C_diagnose", 2))[1][0]) /
                       float(diag_gain(out("ur10_C_diagnose", 2))[0][0])),
        lambda: diag_gain(out("ur10_C_diagnose", 2))[0][1],
        lambda: diag_gain(out("ur10_C_diagnose", 2))[1][1],
        lambda: float(diag_gain(out("ur10_C_diagnose", 2))[1][0]) /
        float(grep(r"noise floor ([\d.]+) mm", out("ur10_C_diagnose", 2))),
        lambda: grep(r"noise floor ([\d.]+) mm", out("ur10_C_diagnose", 2)),
        lambda: diag_gain(out("ur10_C_diagnose", 2))[2][0],
        lambda: validation(js("ur10_C_diagnose", 3), "extended")["mean_position_mm"]),
    Fig("docs/diagnosis.md", "`registration_drift (degree {} in time order)` is named (held-out gain {} mm, z {}):\n"
        "the measured tip moves by {} mm RMS, {} mm at most over the series. No joint's zero drift\n"
        "with temperature explains anything beside it (best z {}); `temp_c` and the time order correlate\nat r = {}",
        "ur10_C_diagnose",
        *(lambda k=k: grep(r"round \d+, registration_drift \(degree (\d+) in time order\):.*moves by ([\d.]+) mm RMS, "
                           r"([\d.]+) mm at most \(held-out gain ([\d.]+) mm, z ([\d.]+)\)", out("ur10_C_diagnose", 2), k)
          for k in (1, 4, 5, 2, 3)),
        lambda: grep(r"joint_zero_drift \(joint \d\): removes [\d.]+ % held out, z ([\d.-]+)\)", out("ur10_C_diagnose", 2)),
        lambda: grep(r"correlate at r = ([\d.-]+)", out("ur10_C_diagnose", 2))),
    Fig("docs/diagnosis.md", "the fit rows' mean error goes\n{-} → {} mm", "ur10_C_diagnose",
        lambda: grep(r"after: \d+ fit rows, position error mean ([\d.]+) mm", out("ur10_C_diagnose", 2))),
    Fig("docs/diagnosis.md", "`registration_drift (degree {} in time order)` (z {}), the\ntip moved by {} mm RMS, {} mm at most; "
        "no joint's zero drift beside it (best z {}); r =\n{}; the `seq` trend (z {-}) is gone and the `temp_c` one goes "
        "from z {-} ({-} mm) to z {}\n({} mm)", "ur10_series",
        lambda: series_drift("A")["order"], lambda: series_drift("A")["z_statistic"],
        lambda: series_drift("A")["tip_motion_rms_mm"], lambda: series_drift("A")["tip_motion_max_mm"],
        lambda: grep(r"joint_zero_drift \(joint \d\): removes [\d.]+ % held out, z ([\d.-]+)\)",
                     series_json("A.diagnosis.json")["drift"]["text"]),
        lambda: series_json("A.diagnosis.json")["drift"]["seq_temp_correlation"],
        lambda: grep(r"trend in temp_c is left \(([\d.]+) mm held out, z ([\d.]+)\)",
                     series_json("A.diagnosis.json")["drift"]["text"], 2),
        lambda: grep(r"trend in temp_c is left \(([\d.]+) mm held out, z ([\d.]+)\)",
                     series_json("A.diagnosis.json")["drift"]["text"], 1)),
    Fig("README.md", "Held out, **{} → {} mm** mean (−{} %;\n`poe+gpr` {} mm)", "ur10_C_diagnose",
        lambda: diag_gain(out("ur10_C_diagnose", 2))[0][0],
        lambda: diag_gain(out("ur10_C_diagnose", 2))[1][0],
        lambda: 100 * (1 - float(diag_gain(out("ur10_C_diagnose", 2))[1][0]) /
                       float(diag_gain(out("ur10_C_diagnose", 2))[0][0])),
        lambda: diag_gain(out("ur10_C_diagnose", 2))[2][0]),
    Fig("README.md", "it takes the geometric model's\n  held-out error from {} to {} mm", "ur10_C_diagnose",
        lambda: diag_gain(out("ur10_C_diagnose", 2))[0][0],
        lambda: diag_gain(out("ur10_C_diagnose", 2))[1][0]),
    # one model, one held-out error: diagnose's gain is validate's on the model it wrote
    Fig("README.md", "Held out, **{} → {} mm** mean", "ur10_C_diagnose",
        lambda: diag_gain(out("ur10_C_diagnose", 2))[0][0],
        lambda: validation(js("ur10_C_diagnose", 3), "extended")["mean_position_mm"]),
    Fig("docs/diagnosis.md", "the diagnosis now names and takes out ({-} → {} mm held out", "ur10_C_diagnose",
        lambda: validation(js("ur10_C_diagnose", 3), "extended")["mean_position_mm"]),
    Fig("README.md", "the extended model from `stepcal diagnose` ({} mm) exists only at run time", "ur10_C_diagnose",
        lambda: validation(js("ur10_C_diagnose", 3), "extended")["mean_position_mm"]),
    Fig("docs/diagnosis.md", "build/bin/stepcal calibrate out/ur10-C-twin     # poe: {} / {} mm on the fit / held-out rows",
        "ur10_C_twin", *(lambda s=s: accuracy_table(out("ur10_C_twin", 1), s, 0.0, "poe")[0]
                         for s in ("geometry", "validation"))),
    Fig("docs/diagnosis.md", "build/bin/stepcal calibrate out/ur10-C          # poe: {} / {} mm", "ur10_C_twin",
        *(lambda s=s: accuracy_table(out("ur10_C_twin", 2), s, 0.0, "poe")[0] for s in ("geometry", "validation"))),
    Fig("docs/diagnosis.md", "| fit rows, mean | {} mm |", "ur10_C_twin",
        lambda: accuracy_table(out("ur10_C_twin", 2), "geometry", 0.0, "poe")[0]),
    Fig("docs/diagnosis.md", "| held-out rows, mean | {} mm |", "ur10_C_twin",
        lambda: accuracy_table(out("ur10_C_twin", 2), "validation", 0.0, "poe")[0]),
    # README and docs/diagnosis.md: tools/ur10_series.sh's table
    *(series_row(doc, label, key) for doc in ("README.md", "docs/diagnosis.md") for label, key in (
        ("| C→C, rows from 2000 on", "C→C,"), ("| A→A, rows from 8000 on", "A→A,"),
        ("| A→D (frames refitted on D)", "A→D"), ("| A→B (frames refitted on B)", "A→B"),
        ("| B→C (frames refitted on C)", "B→C"), ("| C→D (frames refitted on D)", "C→D"))),
    drift_row("| C→C, rows from 2000 on (773; 761 covered)", "C-split:C-split"),
    drift_row("| A→A, rows from 8000 on (3911; 3875)", "A-split:A-split"),
    drift_row("| A→D, frames refitted on D (632; 139)", "A:D"),
    drift_row("| A→B, frames refitted on B (1495; 687)", "A:B"),
    drift_row("| B→C, frames refitted on C (2773; 1)", "B:C"),
    drift_row("| C→D, frames refitted on D (632; 6)", "C:D"),
    # docs/certify.md and README: ISO 9283
    Fig("docs/certify.md", "The IRB 4400 gets a cube of edge {} mm centred at\n({}, {}, {}) mm", "iso9283",
        *(lambda k=k: iso_plan_cube(0, k) for k in (1, 2, 3, 4))),
    Fig("docs/certify.md", "the UR10 one of {} mm at ({}, {}, {}) mm", "iso9283",
        *(lambda k=k: iso_plan_cube(1, k) for k in (1, 2, 3, 4))),
    Fig("docs/certify.md", "rated load ({} and {} kg for the IRB 4400/60: {} rows)", "iso9283",
        lambda: grep(r"loads: 0 kg ([\d.]+) kg", out("iso9283", 0)),
        lambda: grep(r"loads: 0 kg [\d.]+ kg ([\d.]+) kg", out("iso9283", 0)),
        lambda: grep(r"rows: (\d+);", out("iso9283", 0))),
    Fig("docs/certify.md", "unloaded only\n({} rows for the UR10", "iso9283",
        lambda: grep(r"rows: (\d+);", out("iso9283", 1))),
    *(iso_twin_row(load) for load in (0, 6, 60)),
    iso_ur10_row("D", 5), iso_ur10_row("B", 6),
    Fig("README.md", "misses by {} mm at its rated 60 kg as\ncommanded and by {} mm corrected, with RP_l (cycles pooled) {} mm",
        "iso9283_readme",
        lambda: iso_figure("iso9283_readme", 2, 60, 0, "AP_P (largest over the poses)"),
        lambda: iso_figure("iso9283_readme", 2, 60, 1, "AP_P (largest over the poses)"),
        lambda: iso_figure("iso9283_readme", 2, 60, 0, "RP_l (cycles pooled)")),
    Fig("README.md", "median AP_P is {} mm as commanded and {} mm corrected, the median RP_l {} mm", "iso9283_ur10",
        lambda: iso_figure("iso9283_ur10", 5, 0, 0, "AP_P (median of the poses)"),
        lambda: iso_figure("iso9283_ur10", 5, 0, 1, "AP_P (median of the poses)"),
        lambda: iso_figure("iso9283_ur10", 5, 0, 0, "RP_l (median of the poses)")),
]

# ---- comparing ------------------------------------------------------------------------------

NUMBER = r"[-−]?\d+(?:[  ]\d{3})*(?:\.\d+)?(?:e[-−+]?\d+)?"


def parse(text):
    """A printed number: (value, half a unit of its last printed digit)."""
    text = str(text).replace("−", "-").replace(" ", "").replace(" ", "")
    mantissa, _, exponent = text.partition("e")
    decimals = len(mantissa.partition(".")[2])
    scale = 10.0 ** int(exponent or 0)
    return float(text), 0.5 * 10.0 ** -decimals * scale


def words_pattern(words):
    """A regex of the doc's words: {} and {-} a number (group), any run of whitespace any other."""
    pattern = ""
    for token in re.split(r"(\{-?\}|\s+)", words):
        if token in ("{}", "{-}"):  # a figure, bold or not
            pattern += rf"\**({NUMBER})\**"
        elif token and token.isspace():
            pattern += r"\s+"
        elif token:
            pattern += re.escape(token)
    return pattern


def agree(doc_figure, code_value):
    doc_value, doc_half = parse(doc_figure)
    if isinstance(code_value, float):
        code, code_half = code_value, 0.0
    else:
        code, code_half = parse(code_value)
    slack = 1e-9 * max(1.0, abs(code))
    if code_half == doc_half:  # printed alike: the same figure
        return abs(doc_value - code) <= slack
    return abs(doc_value - code) <= doc_half + code_half + slack


def check(fig, docs, report):
    """Compares one Fig; returns the number of problems. report(line) prints a line."""
    text = docs[fig.doc]
    matches = list(re.finditer(words_pattern(fig.words), text))
    if len(matches) != 1:
        report(f"{fig.doc}: {'not found' if not matches else f'{len(matches)} places match'}: "
               f"{fig.words!r} (run {fig.run})")
        return 1
    m = matches[0]
    line = text.count("\n", 0, m.start()) + 1
    checked = [g for g, tok in zip(m.groups(), re.findall(r"\{-?\}", fig.words)) if tok == "{}"]
    spans = [m.span(i + 1) for i, tok in enumerate(re.findall(r"\{-?\}", fig.words)) if tok == "{}"]
    problems = 0
    for doc_figure, span, value in zip(checked, spans, fig.values):
        at = f"{fig.doc}:{text.count(chr(10), 0, span[0]) + 1}"
        context = " ".join(text[max(0, span[0] - 40):span[0]].split()[-4:])
        try:
            code = value()
        except (LookupError, StopIteration, ValueError, OSError) as e:
            report(f"{at}: {doc_figure} (after '{context}'): the code's value not found: {e}")
            problems += 1
            continue
        if isinstance(code, int) and not isinstance(code, bool):
            code = str(code)
        try:
            ok = agree(doc_figure, code)
        except ValueError:
            report(f"{at}: {doc_figure} (after '{context}'): the code printed '{code}', not a number")
            problems += 1
            continue
        shown = code if isinstance(code, str) else f"{code:.6g}"
        line_text = (f"{at}: {'ok  ' if ok else 'DIFF'} doc {doc_figure:>12}  code {shown:>12}  "
                     f"(after '{context}'; run {fig.run})")
        if ARGS.print:
            print(line_text)
        if not ok:
            report(line_text)
        problems += not ok
    if len(checked) != len(fig.values):
        report(f"{fig.doc}:{line}: {len(checked)} figures in the words, {len(fig.values)} values")
        problems += 1
    return problems


# ---- running --------------------------------------------------------------------------------


def documented(run, docs):
    """Each command of the run appears in its doc as written (or as EXPANDED says)."""
    missing = []
    for command in run.commands:
        shown = EXPANDED.get(command, command)
        if re.sub(r"[ \t]+", " ", shown) not in re.sub(r"[ \t]+", " ", docs[run.doc]):
            missing.append(f"{run.doc}: run {run.name}: the command is not in the doc: {shown}")
    return missing


def prepare_work(build):
    WORK.mkdir(parents=True, exist_ok=True)
    for name, target in (("build", build), ("tools", SOURCE / "tools"), ("tests", SOURCE / "tests"),
                         ("robots", SOURCE / "robots")):
        link = WORK / name
        if link.is_symlink() or link.exists():
            link.unlink()
        link.symlink_to(target)


def execute(run):
    """Runs the commands in one shell, each one's stdout kept; returns an error text or None."""
    if run.name == "counts":  # a count of a partial build is no figure
        unbuilt = [p.stem for p in (SOURCE / "tests").glob("test_*.cpp") if not (WORK / "build/bin" / p.stem).exists()]
        if unbuilt:
            return "skipped"
    marker = "@@first-day-command-end@@"
    script = "" if run.any_status else "set -e\n"
    for command in run.commands:  # a doc's "$ " prompt is not part of the command
        command = command[2:] if command.startswith("$ ") else command
        script += f"{command}\nstatus=$?; echo {marker}; (exit $status)\n"
    if run.netns:
        # the daemon in the background, its lines kept; the clients once it serves
        script = script.replace(" &\n", " >out/daemon.log 2>&1 &\n"
                                "for i in $(seq 200); do grep -q serving out/daemon.log && break; sleep 0.05; done\n")
        script += "cat out/daemon.log; kill %1\n"
        argv = [str(SOURCE / "tests/system/in_netns.sh"), "bash", "-c", script]
    else:
        argv = ["bash", "-c", script]
    started = time.monotonic()
    result = subprocess.run(argv, cwd=WORK, capture_output=True, text=True)
    run.seconds = time.monotonic() - started
    parts = result.stdout.split(marker + "\n")
    if run.netns and result.returncode == 77:
        return "skipped"
    if result.returncode != 0:
        return (f"run {run.name} failed (status {result.returncode}) at command {len(parts)} of "
                f"{len(run.commands)}:\n{result.stdout[-2000:]}{result.stderr[-2000:]}")
    run.outputs = parts[:len(run.commands)]
    if run.netns:  # the daemon's own lines, printed at its end, stand in its command's place
        run.outputs[1] = parts[-1]
    (WORK / "logs").mkdir(exist_ok=True)
    (WORK / "logs" / f"{run.name}.json").write_text(json.dumps(run.outputs))
    return None


def reuse(run):
    """The outputs the last run of these commands here kept (--again)."""
    kept = WORK / "logs" / f"{run.name}.json"
    if not kept.exists():
        return f"run {run.name}: --again, but it has not run in {WORK} yet"
    run.outputs, run.seconds = json.loads(kept.read_text()), 0.0
    return None


def main():
    global ARGS, WORK
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--build", default=str(SOURCE / "build"))
    parser.add_argument("--work")
    parser.add_argument("--only")
    parser.add_argument("--slow", action="store_true")
    parser.add_argument("--slow-only", action="store_true")
    parser.add_argument("--print", action="store_true")
    parser.add_argument("--list", action="store_true")
    parser.add_argument("--again", action="store_true")
    ARGS = parser.parse_args()
    build = Path(ARGS.build).resolve()
    WORK = Path(ARGS.work).resolve() if ARGS.work else build / "first-day"
    if ARGS.list:
        for run in RUNS:
            print(f"{run.name} ({run.doc}{', slow' if run.slow else ''}):")
            for command in run.commands:
                print("  " + command)
        return 0
    if ARGS.only:
        chosen = [r for r in RUNS if r.name in ARGS.only.split(",")]
    else:
        chosen = [r for r in RUNS if (r.slow if ARGS.slow_only else ARGS.slow or not r.slow)]
    for run in list(chosen):
        if run.needs and RUN[run.needs] not in chosen:
            chosen.insert(chosen.index(run), RUN[run.needs])
    unknown = set(ARGS.only.split(",")) - set(RUN) if ARGS.only else set()
    if unknown:
        print(f"first_day: --only {','.join(sorted(unknown))}: no such run (--list)", file=sys.stderr)
        return 2
    docs = {p: (SOURCE / p).read_text() for p in {"README.md"} | {r.doc for r in RUNS} |
            {f.doc for f in FIGS}}
    problems = []
    for run in chosen:
        problems += documented(run, docs)
    prepare_work(build)
    skipped = set()
    for run in chosen:
        for stale in ("out/ur10-series",) if run.name == "ur10_series" and not ARGS.again else ():
            shutil.rmtree(WORK / stale, ignore_errors=True)
        error = reuse(run) if ARGS.again else execute(run)
        for _ in range(2):
            if not (error and run.retry_on and run.retry_on in error):
                break
            print(f"first_day: run {run.name}: {run.retry_on} (a loaded machine); once more")
            error = execute(run)
        if error == "skipped":
            print(f"first_day: run {run.name} skipped: {run.note}: not here")
            skipped.add(run.name)
        elif error:
            problems.append(error)
            skipped.add(run.name)
        else:
            print(f"first_day: run {run.name}: {len(run.commands)} commands, {run.seconds:.1f} s")
    count = 0
    for fig in FIGS:
        if fig.run in {r.name for r in chosen} - skipped:
            check(fig, docs, problems.append)
            count += len([t for t in re.findall(r"\{-?\}", fig.words) if t == "{}"])
    if problems:
        print("first_day: the docs and the code differ (fix the doc, or the code if it is wrong):")
    for p in problems:
        print(p)
    print(f"first_day: {count} figures of {len(chosen) - len(skipped)} runs checked; "
          f"{len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
