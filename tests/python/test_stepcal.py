"""The Python module stepcal against the C++ API and the command line (ctest python_bindings and,
in a private network namespace, python_client; tests/CMakeLists.txt sets the environment):

  STEPCAL_BIN_DIR      the build's executables (stepcal, stepcal-runtime)
  STEPCAL_CAMPAIGN     a twin campaign (the can_e2e fixture's, seed 4) and
  STEPCAL_MODEL        its calibrated model file
  STEPCAL_REFERENCE    tests/python/runtime_reference: the C++ runtime's answers on that campaign
  STEPCAL_OLD_DAEMON   tests/python/old_daemon: a daemon of message version 1 or 2 (refusals only)
  STEPCAL_DOCS_DIR     docs/, whose python.md holds the example script run here
"""
import enum
import json
import math
import os
import re
import shutil
import subprocess
import time

import numpy as np
import pytest

import stepcal

BIN = os.environ["STEPCAL_BIN_DIR"]
CAMPAIGN = os.environ["STEPCAL_CAMPAIGN"]
MODEL = os.environ["STEPCAL_MODEL"]
TOLERANCE = 1e-12


def run_json(*args):
    out = subprocess.run([os.path.join(BIN, "stepcal"), *args, "--json"], check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out)


def assert_same(python, cli, path="report"):
    """Equal JSON-like trees: numbers within 1e-12 (relative above 1), wall times skipped."""
    if isinstance(cli, dict):
        assert isinstance(python, dict) and set(python) == set(cli), path
        for key in cli:
            if not key.startswith("seconds") and key != "timing_s":
                assert_same(python[key], cli[key], path + "." + key)
    elif isinstance(cli, list):
        assert isinstance(python, list) and len(python) == len(cli), path
        for i, (p, c) in enumerate(zip(python, cli)):
            assert_same(p, c, "%s[%d]" % (path, i))
    elif isinstance(cli, float) or isinstance(python, float):
        assert abs(python - cli) <= TOLERANCE * max(1.0, abs(cli)), (path, python, cli)
    else:
        assert python == cli, (path, python, cli)


@pytest.fixture(scope="module")
def campaign():
    return stepcal.Campaign.load(CAMPAIGN)


@pytest.fixture(scope="module")
def model():
    return stepcal.Model.load(MODEL)


def test_campaign_columns(campaign):
    rows = campaign.measurements
    n = len(campaign)
    assert campaign.joint_count == 6
    assert rows["q_rad"].shape == (n, 6) and rows["pose"].shape == (n, 4, 4)
    assert set(rows["set"]) == {"geometry", "stiffness", "residual", "validation"}
    np.testing.assert_array_equal(rows["pose"][:, :3, 3], rows["position_m"])


def fresh_report(call):
    """The report of stepcal.<call> in a new Python process, as the command line runs it: the
    trainer's results depend in their last bits on whether a GPR fit already ran in the process
    (it pins Eigen's cache sizes for the process: trainer/src/gpr.cpp), so that a calibration
    followed by a diagnosis in one process differs from `stepcal diagnose` by up to ~1e-9 in
    ill-conditioned candidates."""
    code = ("import json, stepcal\n"
            "c = stepcal.Campaign.load(%r)\n"
            "print(json.dumps(stepcal.%s.report))" % (CAMPAIGN, call))
    out = subprocess.run([os.environ.get("STEPCAL_PYTHON", "/usr/bin/python3"), "-c", code],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def test_calibrate_gives_the_command_lines_numbers(campaign):
    assert_same(fresh_report("calibrate(c)"), run_json("calibrate", CAMPAIGN))
    calibration = stepcal.calibrate(campaign)
    table = calibration.accuracy
    assert len(table["method"]) == len(table["mean_position_mm"]) > 0
    assert isinstance(table["mean_position_mm"], np.ndarray)
    # Every group of rows, each with its set: the report's validation and fit tables together.
    assert set(table["set"]) == {"geometry", "stiffness", "residual", "validation"}
    report = calibration.report
    assert len(table["set"]) == len(report["validation"]) + len(report["fit"])
    validation = [i for i, s in enumerate(table["set"]) if s == "validation"]
    assert [table["method"][i] for i in validation] == [r["method"] for r in report["validation"]]
    np.testing.assert_array_equal(table["mean_position_mm"][validation],
                                  [r["mean_position_mm"] for r in report["validation"]])
    assert calibration.row_position_errors_mm["poe"].shape == (len(campaign),)
    assert calibration.model.joint_count == 6


def test_campaigns_of_one_robot_are_calibrated_together(campaign):
    merged = stepcal.Campaign.merge([campaign, campaign])
    assert merged.sessions == 2 and campaign.sessions == 1
    assert len(merged) == 2 * len(campaign)
    sessions = stepcal.calibrate(merged).report["sessions"]
    assert len(sessions) == 2
    # The same rows twice: each copy gets the same frames and fit.
    assert sessions[0]["fit_rms_position_mm"] == pytest.approx(sessions[1]["fit_rms_position_mm"], rel=1e-6)
    assert sessions[1]["tool_from_first_mm"] < 1e-6
    # Diagnosed together, the second copy's station and tool are the first's.
    campaigns = stepcal.diagnose(merged).report["campaigns"]
    assert [c["fit_rows"] for c in campaigns] == [campaigns[0]["fit_rows"]] * 2
    for frame in ("station", "tool"):
        assert max(abs(x) for x in campaigns[1][frame]["translation_mm"]) < 1e-3
        assert max(abs(x) for x in campaigns[1][frame]["rotation_deg"]) < 1e-4


def test_diagnose_gives_the_command_lines_numbers(campaign, model):
    cli = run_json("diagnose", CAMPAIGN, "--model", MODEL)
    assert_same(fresh_report("diagnose(c, model=stepcal.Model.load(%r))" % MODEL), cli)
    diagnosis = stepcal.diagnose(campaign, model=model)
    assert diagnosis.verdict == cli["verdict"]
    assert [e["name"] for e in diagnosis.effects] == [e["name"] for e in cli["effects"]]
    for effect in diagnosis.effects:  # each found effect with its parameters and 1-σ
        assert "name" in effect and "parameters" in effect and "uncertainty" in effect
    assert isinstance(diagnosis.gain["load_kg"], np.ndarray)
    # The gain's columns name their model: before_gpr_* is the report's gpr_* (the starting
    # model with its GPR), after_gpr_* the extended model with its refitted GPR.
    gain = cli["gain"]
    assert not [key for key in diagnosis.gain if key.startswith("gpr_")]
    for key in ("before_gpr_mean_position_mm", "after_gpr_mean_position_mm",
                "before_mean_position_mm", "after_mean_position_mm"):
        assert key in diagnosis.gain, key
    for python_key, cli_key in (("before_gpr_mean_position_mm", "gpr_mean_position_mm"),
                                ("after_gpr_mean_position_mm", "after_gpr_mean_position_mm")):
        cli_column = np.array([g[cli_key] for g in gain], float)  # null: NaN
        np.testing.assert_allclose(diagnosis.gain[python_key], cli_column, rtol=1e-6)


def test_runtime_gives_the_cpp_apis_numbers(campaign, model):
    reference = subprocess.run([os.environ["STEPCAL_REFERENCE"], MODEL, CAMPAIGN], check=True,
                               capture_output=True, text=True).stdout.split("\n")
    forward = np.array([line.split()[1:] for line in reference if line.startswith("F ")], float)
    inverse = np.array([line.split()[1:] for line in reference if line.startswith("I ")], float)
    rows = campaign.measurements
    validation = np.array(rows["set"]) == "validation"
    q = rows["q_rad"][validation]
    wrench = np.nan_to_num(rows["wrench"][validation])
    temp_c = rows["temp_c"][validation]
    assert len(q) == len(forward) > 50

    result = model.correct_forward(q, wrench=wrench, temp_c=temp_c)
    np.testing.assert_array_equal(result.status, forward[:, 0])
    np.testing.assert_allclose(result.position_m, forward[:, 1:4], rtol=0, atol=TOLERANCE)
    np.testing.assert_allclose(result.quaternion_wxyz, forward[:, 4:8], rtol=0, atol=TOLERANCE)
    np.testing.assert_allclose(result.gpr_std, forward[:, 8:14], rtol=0, atol=TOLERANCE)
    np.testing.assert_allclose(result.pose[:, :3, 3], result.position_m, rtol=0, atol=0)

    offsets = np.where(np.arange(len(q)) % 2 == 0, 2.0, -2.0) * math.pi / 180.0
    seeds = q + offsets[:, None]
    solved = model.solve_inverse(rows["pose"][validation], seed=seeds, wrench=wrench,
                                 temp_c=temp_c)
    np.testing.assert_array_equal(solved.status, inverse[:, 0])
    np.testing.assert_allclose(solved.q_target_rad, inverse[:, 1:7], rtol=0, atol=TOLERANCE)
    np.testing.assert_array_equal(solved.iterations, inverse[:, 7])
    assert (solved.status == stepcal.Status.OK).mean() > 0.9
    # Each answer states its accuracy (the model file has the calibration's factors): a 95 %
    # bound above the tracker's stated noise, the inverse's at its answer as the forward's there.
    assert np.all(result.position_bound_m > 1e-6) and np.all(result.orientation_bound_rad > 0)
    ok = solved.status == stepcal.Status.OK
    np.testing.assert_allclose(solved.position_bound_m[ok], result.position_bound_m[ok], rtol=0.05)

    # One row in, one row's values out; statuses as the enum.
    one = model.correct_forward(q[0], wrench=wrench[0], temp_c=temp_c[0])
    assert one.status == stepcal.Status(int(forward[0, 0]))
    np.testing.assert_allclose(one.position_m, forward[0, 1:4], rtol=0, atol=TOLERANCE)


def test_statuses_per_row(model):
    q = np.zeros((3, 6))
    q[1, 2] = np.nan
    result = model.correct_forward(q)
    assert result.status[1] == stepcal.Status.BAD_REQUEST
    assert stepcal.Status(int(result.status[0])) in (stepcal.Status.OK, stepcal.Status.OUT_OF_DOMAIN)
    not_unit = np.array([1.0, 0.5, 1.0, 2.0, 0.0, 0.0, 0.0])  # quaternion of norm 2
    assert model.solve_inverse(not_unit, seed=np.zeros(6)).status == stepcal.Status.BAD_REQUEST
    # The statuses of many rows are int8 values of stepcal.Status; status_names names them.
    assert issubclass(stepcal.Status, enum.IntEnum) and isinstance(stepcal.Status.OK, int)
    names = stepcal.status_names(result.status)
    assert names[1] == "BAD_REQUEST" and len(names) == 3
    assert names == [stepcal.Status(int(s)).name for s in result.status]
    assert stepcal.status_names(stepcal.Status.STALE_WRENCH) == "STALE_WRENCH"
    assert [s.name for s in stepcal.Status] == ["OK", "NOT_CONVERGED", "STALE_WRENCH",
                                                "OUT_OF_DOMAIN", "UNREACHABLE", "NEAR_SINGULAR",
                                                "BAD_REQUEST"]


def matrix_of(row):
    """A (4, 4) transform of x, y, z [m], qw, qx, qy, qz."""
    w, x, y, z = row[3:]
    out = np.eye(4)
    out[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                   [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                   [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]
    out[:3, 3] = row[:3]
    return out


TOOL = np.array([0.05, -0.02, 0.3, math.cos(0.2), 0.0, math.sin(0.2), 0.0])  # 0.3 m out, 23° tilt
USER_FRAME = np.array([1.1, -0.4, 0.2, math.cos(0.4), 0.0, 0.0, math.sin(0.4)])


def validation_joints(campaign, count):
    rows = campaign.measurements
    return rows["q_rad"][np.array(rows["set"]) == "validation"][:count]


def test_call_terms_tool_frame_and_payload(model, campaign):
    q = validation_joints(campaign, 20)
    own = model.correct_forward(q)
    tooled = model.correct_forward(q, terms=stepcal.CallTerms(tool=TOOL))
    # The tool hangs rigidly from the corrected target.
    np.testing.assert_allclose(tooled.pose, own.pose @ matrix_of(TOOL), rtol=0, atol=1e-12)
    # The base frame is the tracker frame moved by one fixed transform, the same for every row.
    base = model.correct_forward(q, terms=stepcal.CallTerms(frame="base", tool=TOOL))
    X_TrackerBase = tooled.pose[0] @ np.linalg.inv(base.pose[0])
    np.testing.assert_allclose(X_TrackerBase @ base.pose, tooled.pose, rtol=0, atol=1e-9)
    user = model.correct_forward(q, terms=stepcal.CallTerms(frame="user", user_frame=USER_FRAME,
                                                            tool=TOOL))
    np.testing.assert_allclose(matrix_of(USER_FRAME) @ user.pose, base.pose, rtol=0, atol=1e-12)

    # A payload is its weight at the deflected pose: the wrench the call reports gives the same
    # pose when it is given as a wrench, and it weighs the payload's mass.
    load = dict(tool=TOOL, payload_kg=40.0, cog_m=[0.0, 0.0, 0.1], cog_frame="tool")
    loaded = model.correct_forward(q, terms=stepcal.CallTerms(**load))
    given = model.correct_forward(q, wrench=loaded.wrench, terms=stepcal.CallTerms(tool=TOOL))
    np.testing.assert_allclose(given.pose, loaded.pose, rtol=0, atol=1e-9)
    unloaded = model.correct_forward(q, terms=stepcal.CallTerms(tool=TOOL, payload_kg=0.0))
    weight_N = np.linalg.norm(loaded.wrench[:, :3] - unloaded.wrench[:, :3], axis=1)
    np.testing.assert_allclose(weight_N, 40.0 * 9.80665, rtol=2e-3)
    assert np.abs(loaded.position_m - tooled.position_m).max() > 1e-5  # the twin is compliant

    # The inverse in the same terms returns to the joints.
    seeds = q + 2 * math.pi / 180
    for terms, poses in ((stepcal.CallTerms(frame="base", tool=TOOL), base.pose),
                         (stepcal.CallTerms(**load), loaded.pose)):
        solved = model.solve_inverse(poses, seed=seeds, terms=terms)
        assert np.isin(solved.status, [stepcal.Status.OK, stepcal.Status.OUT_OF_DOMAIN]).all()
        np.testing.assert_allclose(solved.q_target_rad, q, rtol=0, atol=1e-5)
        np.testing.assert_allclose(solved.predicted_position_m, poses[:, :3, 3], rtol=0, atol=1e-6)


def test_call_terms_refuse_what_does_not_hold(model):
    for kwargs, message in (
            (dict(frame="world"), "frame 'world': expected tracker | base | user"),
            (dict(frame="user"), "user_frame goes with frame='user'"),
            (dict(user_frame=USER_FRAME), "user_frame goes with frame='user'"),
            (dict(tool=[0, 0, 0, 2, 0, 0, 0]), "tool: quaternion of norm 2"),
            (dict(tool=np.eye(4)[:3]), "tool: expected a (4, 4) matrix or 7 numbers"),
            (dict(tool=2 * np.eye(4)), "tool: expected a homogeneous transform"),
            (dict(tool_from="wrist"), "tool_from 'wrist': expected target | flange"),
            (dict(payload_kg=-1.0), "payload_kg -1"),
            (dict(cog_m=[0, 0, 0.1]), "cog_m goes with payload_kg"),
            (dict(payload_kg=1.0, cog_m=[0, 0]), "cog_m: expected shape (3,)")):
        with pytest.raises(ValueError, match=re.escape(message)):
            stepcal.CallTerms(**kwargs)
    with pytest.raises(TypeError):
        stepcal.CallTerms("base")  # keywords only
    with pytest.raises(ValueError, match="give one load, not both"):
        model.correct_forward(np.zeros(6), wrench=np.zeros(6),
                              terms=stepcal.CallTerms(payload_kg=1.0))
    with pytest.raises(TypeError, match="terms: expected a stepcal.CallTerms"):
        model.correct_forward(np.zeros(6), terms="base")
    assert repr(stepcal.CallTerms(frame="base", payload_kg=2.0)).startswith(
        "stepcal.CallTerms(frame='base'")


def test_model_files_round_trip(tmp_path, model, campaign):
    copy = tmp_path / "copy.stepcal"
    model.save(str(copy))
    assert copy.read_bytes() == open(MODEL, "rb").read()
    assert stepcal.Model.load(str(copy)).model_id == model.model_id
    # The id is an int shown as the 16 hex digits stepcal-client and the daemon print.
    model_id = model.model_id
    assert isinstance(model_id, int) and isinstance(model_id, stepcal.ModelId)
    assert re.fullmatch(r"[0-9a-f]{16}", str(model_id)) and int(str(model_id), 16) == model_id
    assert repr(model_id) == str(model_id) == "%s" % model_id == "{}".format(model_id)
    assert "%d" % model_id == str(int(model_id))
    assert "joints" in model.describe()


def test_bad_input_raises_with_the_same_message(tmp_path, model):
    with pytest.raises(stepcal.InputError) as missing:
        stepcal.Campaign.load(str(tmp_path / "none"))
    assert str(tmp_path / "none") in str(missing.value)

    broken = tmp_path / "broken"
    shutil.copytree(CAMPAIGN, broken)
    lines = (broken / "measurements.csv").read_text().split("\n")
    header = lines[0].split(",")
    cells = lines[3].split(",")
    cells[header.index("x_mm")] = "12.5x"
    lines[3] = ",".join(cells)
    (broken / "measurements.csv").write_text("\n".join(lines))
    with pytest.raises(stepcal.InputError) as bad_row:
        stepcal.Campaign.load(str(broken))
    error = bad_row.value
    assert isinstance(error, ValueError)
    assert error.line == 4 and error.column == "x_mm"
    assert error.file.endswith("measurements.csv")
    cli = subprocess.run([os.path.join(BIN, "stepcal"), "calibrate", str(broken)],
                         capture_output=True, text=True)
    assert cli.returncode == 2 and str(error) in cli.stderr

    # A file where the campaign folder is expected: one short line, not the file's content.
    big = tmp_path / "measurements.csv"
    big.write_text((broken / "measurements.csv").read_text() * 4)
    assert big.stat().st_size > 100000
    with pytest.raises(stepcal.InputError) as a_file:
        stepcal.Campaign.load(str(big))
    message = str(a_file.value)
    assert "is a file; expected a campaign folder holding campaign.yaml" in message
    assert "\n" not in message and len(message) < 300, message[:400]
    with pytest.raises(stepcal.InputError, match="is a folder; expected a stepcal model file"):
        stepcal.Model.load(str(tmp_path))

    garbage = tmp_path / "garbage.stepcal"
    garbage.write_bytes(b"not a model at all")
    with pytest.raises(stepcal.InputError, match="not a stepcal model file"):
        stepcal.Model.load(str(garbage))
    with pytest.raises(ValueError, match=r"expected shape \(6,\) or \(N, 6\), got \(2, 5\)"):
        model.correct_forward(np.zeros((2, 5)))
    with pytest.raises(stepcal.InputError, match="gpr_points 1"):
        stepcal.calibrate(stepcal.Campaign.load(CAMPAIGN), gpr_points=1)


def test_a_model_refuses_another_robots_campaign_by_name(tmp_path, model):
    ur10 = str(tmp_path / "ur10")
    subprocess.run([os.path.join(BIN, "stepcal"), "simulate", "--robot", "ur10", "--seed", "1",
                    "--out", ur10], check=True, capture_output=True)
    expected = ("the model's joints (joint_1, joint_2, joint_3, joint_4, joint_5, joint_6) are not "
                "the campaign's (shoulder_pan_joint, shoulder_lift_joint")
    with pytest.raises(stepcal.InputError, match=re.escape(expected)):
        stepcal.diagnose(stepcal.Campaign.load(ur10), model=model)


def test_the_docs_example_runs(tmp_path):
    text = open(os.path.join(os.environ["STEPCAL_DOCS_DIR"], "python.md")).read()
    match = re.search(r"<!-- example, run by tests/python -->\s*```python\n(.*?)```", text, re.S)
    assert match, "docs/python.md: no example block"
    script = match.group(1)
    assert len(script.strip().split("\n")) <= 15
    (tmp_path / "out").mkdir()
    os.symlink(CAMPAIGN, tmp_path / "out" / "camp")
    done = subprocess.run([os.environ.get("STEPCAL_PYTHON", "/usr/bin/python3"), "-c", script],
                          cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "mean error" in done.stdout


# ---- the daemon from Python, over real UDP multicast (ctest python_client, in a netns) ----------

needs_netns = pytest.mark.skipif(not os.environ.get("STEPCAL_NETNS"),
                                 reason="needs a private network namespace (tests/system/in_netns.sh)")


class Daemon:
    """stepcal-runtime on the fixture's model, serving until the block ends. Its budget is long
    (0.1 s): these tests check answers, and a loaded machine's first inverse may take more than
    the default 200 µs (the latency is measured by tests/system/lcm_roundtrip.sh)."""

    def __init__(self, tmp_path, *args):
        self.log_path = tmp_path / "daemon.log"
        self.args = [os.path.join(BIN, "stepcal-runtime"), "--model", MODEL, "--budget-us",
                     "100000", *args]

    def __enter__(self):
        self.process = subprocess.Popen(self.args, stderr=open(self.log_path, "w"))
        for _ in range(100):
            if "serving" in self.log_path.read_text():
                return self
            time.sleep(0.1)
        raise AssertionError("the daemon did not start: " + self.log_path.read_text())

    def __exit__(self, *exc):
        self.process.terminate()
        self.process.wait(timeout=10)


@needs_netns
def test_client_gets_the_daemons_answers(tmp_path, campaign, model):
    rows = campaign.measurements
    i = list(rows["set"]).index("validation")
    q, wrench = rows["q_rad"][i], np.nan_to_num(rows["wrench"][i])
    with Daemon(tmp_path):
        client = stepcal.Client(timeout_ms=2000)
        reply = client.forward(q, wrench=wrench)
        local = model.correct_forward(q, wrench=wrench)
        assert reply.status == local.status
        assert reply.model_id == model.model_id
        np.testing.assert_allclose(reply.predicted_position_m, local.position_m, rtol=0,
                                   atol=TOLERANCE)
        # The stated accuracy travels in the reply, the local call's (the model has ACCU).
        assert math.isfinite(local.position_bound_m) and local.position_bound_m > 0
        np.testing.assert_allclose([reply.position_bound_m, reply.orientation_bound_rad],
                                   [local.position_bound_m, local.orientation_bound_rad],
                                   rtol=1e-12, atol=0)
        assert reply.position_rms_m < reply.position_bound_m
        seed = q + 2 * math.pi / 180
        reply = client.inverse(rows["position_m"][i], rows["quaternion_wxyz"][i], seed,
                               wrench=wrench)
        assert reply.status in (stepcal.Status.OK, stepcal.Status.OUT_OF_DOMAIN)
        assert reply.residual_position_m < 1e-5

        # In the controller's terms: a user frame, a tool and a payload, as the local call.
        terms = stepcal.CallTerms(frame="user", user_frame=USER_FRAME, tool=TOOL, payload_kg=40.0,
                                  cog_m=[0.0, 0.0, 0.1], cog_frame="tool")
        reply = client.forward(q, terms=terms)
        local = model.correct_forward(q, terms=terms)
        assert reply.status == local.status
        np.testing.assert_allclose(reply.predicted_position_m, local.position_m, rtol=0,
                                   atol=TOLERANCE)
        np.testing.assert_allclose(reply.predicted_quaternion_wxyz, local.quaternion_wxyz,
                                   rtol=0, atol=TOLERANCE)
        np.testing.assert_allclose(reply.wrench, local.wrench, rtol=0, atol=1e-9)
        reply = client.inverse(local.position_m, local.quaternion_wxyz, seed, terms=terms)
        assert reply.status in (stepcal.Status.OK, stepcal.Status.OUT_OF_DOMAIN)
        np.testing.assert_allclose(reply.q_target_rad, q, rtol=0, atol=1e-5)
    with pytest.raises(TimeoutError, match="no reply from stepcal-runtime"):
        stepcal.Client(timeout_ms=50).forward(q, wrench=wrench)
    with pytest.raises(stepcal.InputError, match="LCM cannot open it"):
        stepcal.Client("nowhere://")
    with pytest.raises(ValueError, match="q: expected 6 numbers"):
        stepcal.Client().forward([0.0] * 5)


@needs_netns
def test_client_with_the_cell_key(tmp_path, campaign):
    key = tmp_path / "cell.key"
    key.write_bytes(os.urandom(32))
    os.chmod(key, 0o600)
    other = tmp_path / "other.key"
    other.write_bytes(os.urandom(32))
    os.chmod(other, 0o600)
    q = validation_joints(campaign, 1)[0]
    with Daemon(tmp_path, "--key-file", str(key)):
        reply = stepcal.Client(timeout_ms=2000, key_file=str(key)).forward(q, wrench=np.zeros(6))
        assert reply.status in (stepcal.Status.OK, stepcal.Status.OUT_OF_DOMAIN)
        for stranger in (stepcal.Client(timeout_ms=300),
                         stepcal.Client(timeout_ms=300, key_file=str(other))):
            with pytest.raises(TimeoutError):  # the daemon answers only the cell
                stranger.forward(q, wrench=np.zeros(6))
    os.chmod(key, 0o644)
    with pytest.raises(stepcal.InputError, match="cell.key"):
        stepcal.Client(key_file=str(key))


@needs_netns
@pytest.mark.parametrize("version", [1, 2])
def test_client_refuses_a_daemon_of_an_older_message_version_by_name(tmp_path, version):
    # Its old replies are never taken for answers; the timeout says what answered.
    log = tmp_path / "old_daemon.log"
    old = subprocess.Popen([os.environ["STEPCAL_OLD_DAEMON"], stepcal.DEFAULT_LCM_URL,
                            str(version)], stderr=open(log, "w"))
    try:
        for _ in range(100):
            if "serving" in log.read_text():
                break
            time.sleep(0.1)
        with pytest.raises(TimeoutError, match=rf"message version {version} "
                                               rf"\(correction_reply_v{version}_t\): it predates "
                                               r"this client's version 3; update stepcal-runtime"):
            stepcal.Client(timeout_ms=300).forward([0.0] * 6, wrench=np.zeros(6))
    finally:
        old.terminate()
        old.wait(timeout=10)
