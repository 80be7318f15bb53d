"""scripts/test.sh's step protocol (scripts/lib/steps.sh) with fake steps.

A step exits 0 (PASS), 77 (SKIPPED: names what is missing in $ABBE_TEST_NOTES)
or anything else (FAIL); a skipped step never shows PASS and fails under
CI=true; tests skipped inside a passing step are listed as SKIPPED lines.
Also: the skip notes read from pytest's -rs and CTest's logs, the grblHAL
step without snapshots, and the real-data marker (tests/real_data.py).
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
STEPS = REPO / "scripts" / "lib" / "steps.sh"
TESTS = REPO / "host_tools" / "tests"


def run_steps(body: str, ci: bool = False) -> subprocess.CompletedProcess:
    """Source steps.sh, run body (bash), then the summary; its output and exit status."""
    script = f"set -uo pipefail\nt_all=$SECONDS\nsource {STEPS}\n{body}\nsummary || exit 1\n"
    env = {k: v for k, v in os.environ.items() if k not in ("CI", "ABBE_TEST_NOTES")}
    if ci:
        env["CI"] = "true"
    return subprocess.run(["bash", "-c", script], capture_output=True, text=True, env=env, timeout=60)


def summary_lines(out: str) -> list[str]:
    return out.split("==== [test] summary ====\n", 1)[1].splitlines()


FAKES = textwrap.dedent("""
    ok() { echo fine; }
    bad() { return 3; }
    missing() { echo "the frobnicator is absent" >>"$ABBE_TEST_NOTES"; return 77; }
    silent_skip() { return 77; }
    partial() { step_note "pytest: 2 test(s): real data absent: /x"; return 0; }
""")


def test_pass_and_fail():
    r = run_steps(FAKES + 'step "one" ok\nstep "two" bad\n')
    lines = summary_lines(r.stdout)
    assert r.returncode == 1
    assert lines[0].startswith("PASS     one (")
    assert lines[1].startswith("FAIL     two (")
    assert lines[-1].startswith("[test] FAILED: 1 of 2 steps failed")


def test_a_failed_steps_last_lines_are_in_the_summary_a_passing_steps_are_not():
    """CI's record of a run may keep only the summary: a failed step's last lines (stdout and
    stderr, in order, at most FAILED_TAIL_LINES) are there, under its FAIL line; a step that
    is a shell function keeps running in the runner's shell (its variables stay)."""
    body = FAKES + textwrap.dedent("""\
        chatty_bad() { for i in $(seq 1 40); do echo "line $i"; done; echo "why: the oops" >&2; \
            LEFT_BY_STEP=set; return 4; }
        FAILED_TAIL_LINES=5
        step "talks then fails" chatty_bad
        step "ok" ok
        echo "after: ${LEFT_BY_STEP:-unset}"
        """)
    r = run_steps(body)
    assert r.returncode == 1
    assert "line 1\n" in r.stdout and "why: the oops" in r.stdout  # streamed as it came
    assert "after: set" in r.stdout
    lines = summary_lines(r.stdout)
    assert lines[0].startswith("FAIL     talks then fails (")
    assert lines[1] == "         its last lines of output:"
    assert lines[2:7] == ["         | line 37", "         | line 38", "         | line 39",
                          "         | line 40", "         | why: the oops"]
    assert lines[7].startswith("PASS     ok (")
    assert "fine" not in "\n".join(lines)  # a passing step's output is not repeated
    assert lines[-1].startswith("[test] FAILED: 1 of 2 steps failed")


def test_a_process_a_step_leaves_running_does_not_hold_the_run(tmp_path):
    """A step that leaves a process behind holding its output (a daemon) does not make the
    run wait for it: tee is waited for 5 s at most, and the summary waits for the background
    steps by pid, not for every job. Shown without a clock: the run has ended while the
    process it left is still alive (a bare wait would wait for it: the 120 s timeout fails
    the test). The run's output goes to a file here: a pipe would be held open by the
    sleeper through tee, whatever the runner does."""
    pid_file = tmp_path / "sleeper.pid"
    script = (f"set -uo pipefail\nt_all=$SECONDS\nsource {STEPS}\n" + FAKES
              + f'lingering() {{ sleep 600 & echo $! >{pid_file}; echo "left a sleeper"; }}\n'
              + 'step "one" lingering\nstep "two" bad\nsummary || exit 1\n')
    out = tmp_path / "out"
    env = {k: v for k, v in os.environ.items() if k not in ("CI", "ABBE_TEST_NOTES")}
    with out.open("w") as f:
        rc = subprocess.run(["bash", "-c", script], stdout=f, stderr=subprocess.STDOUT, env=env,
                            timeout=120).returncode
    pid = int(pid_file.read_text())
    try:
        os.kill(pid, 0)  # still running: the run did not wait for it
        alive = True
    except ProcessLookupError:
        alive = False
    finally:
        try:
            os.kill(pid, 9)
        except ProcessLookupError:
            pass
    assert alive, "the sleeper ended before the run: the run waited for it"
    assert rc == 1 and summary_lines(out.read_text())[0].startswith("PASS     one (")
    assert "left a sleeper" in out.read_text()


def test_a_failed_background_steps_last_lines_are_in_the_summary():
    body = FAKES + textwrap.dedent("""\
        bg_bad() { echo "first"; echo "bg: it broke"; return 2; }
        step_bg "bg" bg_bad
        step "fg" ok
        step_join "bg"
        """)
    r = run_steps(body)
    lines = summary_lines(r.stdout)
    assert lines[1].startswith("FAIL     bg (")
    assert lines[2:5] == ["         its last lines of output:", "         | first", "         | bg: it broke"]


def test_all_pass_keeps_the_plain_closing_line():
    r = run_steps(FAKES + 'step "one" ok\nstep "two" ok\n')
    assert r.returncode == 0
    assert summary_lines(r.stdout)[-1].startswith("[test] OK: all 2 steps passed (")


def test_skipped_step_is_never_pass_and_names_what_is_missing():
    r = run_steps(FAKES + 'step "one" ok\nstep "gone" missing\nstep "quiet" silent_skip\n')
    lines = summary_lines(r.stdout)
    assert r.returncode == 0  # outside CI a skip is not a failure, but it shows
    gone = [ln for ln in lines if " gone " in ln]
    assert len(gone) == 1 and gone[0].startswith("SKIPPED  gone (")
    assert gone[0].endswith(": the frobnicator is absent")
    assert not any(ln.startswith("PASS") and ("gone" in ln or "quiet" in ln) for ln in lines)
    assert any(ln.startswith("SKIPPED  quiet (") and "the step named no reason" in ln for ln in lines)
    assert lines[-1].startswith("[test] OK: 1 of 3 steps passed, 2 SKIPPED")


def test_skipped_step_fails_under_ci():
    r = run_steps(FAKES + 'step "one" ok\nstep "gone" missing\n', ci=True)
    lines = summary_lines(r.stdout)
    assert r.returncode == 1
    assert any(ln.startswith("SKIPPED  gone (") and ln.endswith("(a failure under CI=true)") for ln in lines)
    assert lines[-1].startswith("[test] FAILED: 1 of 2 steps failed")


def test_skips_inside_a_passing_step_are_listed():
    r = run_steps(FAKES + 'step "py" partial\n')
    lines = summary_lines(r.stdout)
    assert r.returncode == 0
    assert lines[0].startswith("PASS     py (")
    assert lines[1].strip() == "SKIPPED inside it: pytest: 2 test(s): real data absent: /x"
    assert lines[-1].startswith("[test] OK: all 1 steps passed")  # one step; the indented line is not a step


def test_pytest_skip_notes_sum_per_reason(tmp_path):
    log = tmp_path / "pytest.log"
    log.write_text(textwrap.dedent("""\
        ....s..
        =========================== short test summary info ============================
        SKIPPED [2] tests/formats/test_ess.py:27: real data absent: /w/shared/data/ess-target (licence)
        SKIPPED [3] tests/analysis/test_iso230_2.py:22: real data absent: /w/shared/data/ess-target (licence)
        SKIPPED [1] tests/ports/test_can_docs.py: abbe-cand not built: /b/abbe-cand missing
        12 passed, 6 skipped in 3.21s
        """))
    r = run_steps(f'pyskips() {{ pytest_skip_notes {log}; }}\nstep "py" pyskips\n')
    lines = summary_lines(r.stdout)
    inside = sorted(ln.strip() for ln in lines if "SKIPPED inside it" in ln)
    assert inside == [
        "SKIPPED inside it: pytest: 1 test(s): abbe-cand not built: /b/abbe-cand missing",
        "SKIPPED inside it: pytest: 5 test(s): real data absent: /w/shared/data/ess-target (licence)",
    ]


def test_ctest_skip_notes(tmp_path):
    log = tmp_path / "ctest.log"
    log.write_text(textwrap.dedent("""\
        100% tests passed, 0 tests failed out of 40

        The following tests did not run:
        \t 12 - test_can_socket (Skipped)
        """))
    r = run_steps(f'cskips() {{ ctest_skip_notes {log} build; }}\nstep "c" cskips\n')
    lines = summary_lines(r.stdout)
    assert lines[1].strip() == "SKIPPED inside it: build: CTest skipped 1 test(s): test_can_socket"


def test_background_steps_keep_the_order_the_outcomes_and_their_logs(tmp_path):
    """step_bg / step_join: the summary in the joined order (not the finishing order), FAIL,
    SKIPPED and the notes inside a PASS as for a foreground step, each log under its header,
    the background steps one after another."""
    order = tmp_path / "order"
    body = FAKES + textwrap.dedent(f"""\
        slow_ok() {{ sleep 1; echo "slow start $(date +%s%N)" >>{order}; echo "slow says hi"; \
            echo "slow end $(date +%s%N)" >>{order}; }}
        quick_bad() {{ echo "quick start $(date +%s%N)" >>{order}; echo "quick says no"; return 3; }}
        step_bg "bg pass" slow_ok
        step_bg "bg fail" quick_bad
        step_bg "bg skip" missing
        step_bg "bg partial" partial
        step "fg" ok
        step_join "bg pass"
        step_join "bg fail"
        step_join "bg skip"
        step "last" ok
        """)  # "bg partial" never joined: the summary waits for it and lists it
    r = run_steps(body)
    lines = summary_lines(r.stdout)
    assert r.returncode == 1
    steps = [ln for ln in lines if not ln.startswith(" ")]
    assert [ln.split("(")[0].split(None, 1)[1].strip() for ln in steps[:-1]] == [
        "fg", "bg pass", "bg fail", "bg skip", "last", "bg partial"]
    assert steps[1].startswith("PASS     bg pass (") and steps[2].startswith("FAIL     bg fail (")
    assert steps[3].startswith("SKIPPED  bg skip (") and steps[3].endswith(": the frobnicator is absent")
    assert steps[5].startswith("PASS     bg partial (")
    assert lines[-2].strip() == "SKIPPED inside it: pytest: 2 test(s): real data absent: /x"
    assert steps[-1].startswith("[test] FAILED: 1 of 6 steps failed")
    out = r.stdout
    assert out.index("==== [test] bg pass ====") < out.index("slow says hi") < out.index("==== [test] bg fail ====")
    assert out.index("==== [test] bg fail ====") < out.index("quick says no")
    t = {ln.rsplit(" ", 1)[0]: int(ln.rsplit(" ", 1)[1]) for ln in order.read_text().splitlines()}
    assert t["slow end"] <= t["quick start"]  # one lane: the second waits for the first


def test_background_step_failing_fails_the_run_under_its_name():
    r = run_steps(FAKES + 'step_bg "bg" bad\nstep "fg" ok\nstep_join "bg"\n')
    lines = summary_lines(r.stdout)
    assert r.returncode == 1
    assert lines[0].startswith("PASS     fg (") and lines[1].startswith("FAIL     bg (")


def test_grblhal_step_without_snapshots_skips_with_77(tmp_path):
    notes = tmp_path / "notes"
    notes.touch()
    env = dict(os.environ, ABBE_GRBLHAL_VENDOR=str(tmp_path / "none"), ABBE_TEST_NOTES=str(notes))
    r = subprocess.run(["bash", str(REPO / "port" / "grblhal" / "tests" / "run.sh")], capture_output=True,
                       text=True, env=env, timeout=60)
    assert r.returncode == 77, r.stdout + r.stderr
    assert "[grblhal] SKIPPED: no grblHAL snapshots" in r.stdout
    assert str(tmp_path / "none") in notes.read_text()


def test_carried_grblhal_snapshots_are_where_run_sh_looks():
    vendor = REPO / "third_party" / "grblhal"
    assert list(vendor.glob("grblhal-core-*.tar.gz")) and list(vendor.glob("grblhal-simulator-*.tar.gz"))


@pytest.mark.parametrize("ci", [False, True])
def test_real_data_marker_skips_visibly_or_fails_under_ci(tmp_path, ci):
    (tmp_path / "conftest.py").write_text(textwrap.dedent("""\
        from real_data import check_real_data
        def pytest_configure(config):
            config.addinivalue_line("markers", "real_data(path): test")
        def pytest_runtest_setup(item):
            check_real_data(item)
        """))
    (tmp_path / "test_fake.py").write_text(textwrap.dedent(f"""\
        from pathlib import Path
        from real_data import needs_real_data
        @needs_real_data(Path({str(tmp_path / 'absent' / 'x.dat')!r}))
        def test_reads():
            assert False, "must not run without the file"
        @needs_real_data(Path({str(tmp_path / 'conftest.py')!r}))
        def test_present():
            pass
        """))
    env = {k: v for k, v in os.environ.items() if k != "CI"}
    env["PYTHONPATH"] = str(TESTS)
    if ci:
        env["CI"] = "true"
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider", str(tmp_path)],
                       capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)
    if ci:
        assert r.returncode == 1, r.stdout
        assert "real data missing under CI=true" in r.stdout and "1 passed, 1 error" in r.stdout  # fails at set-up
    else:
        assert r.returncode == 0, r.stdout
        assert "SKIPPED [1]" in r.stdout and "real data absent:" in r.stdout
        assert "1 passed, 1 skipped" in r.stdout
