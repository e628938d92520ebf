"""Start-up errors, Ctrl-C and SIGTERM of the node programs, with fake rclpy calls (no ROS
needed).

The subprocess tests deliver SIGINT twice, the way ``ros2 launch`` does (process group plus
launch's forward), at the spacings of issue 39 (0.05 to 2.5 s: during the clean-up, and after
it while the interpreter shuts down), and SIGTERM.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest

from rwhec_ros.ros.process import (
    EXIT_BAD_CONFIG,
    EXIT_OK,
    EXIT_START_FAILED,
    NodeProgram,
    params_file_arguments,
    run_node_program,
    start_failure_message,
)

REPO = Path(__file__).resolve().parents[2]


class Recorder:
    """Fake rclpy calls that record what the program did."""

    def __init__(self):
        self.calls: list[str] = []
        self.fatal: list[str] = []

    def program(self, **kw) -> NodeProgram:
        base = dict(
            name="calibrator",
            init=lambda: self.calls.append("init"),
            build=lambda: self.calls.append("build") or "node",
            spin=lambda built: self.calls.append("spin"),
            stop_steps=lambda built: [lambda: self.calls.append("stop"),
                                      lambda: self.calls.append("destroy")],
            shutdown=lambda: self.calls.append("shutdown"),
            fatal=self.fatal.append,
            argv=["calibrator"],
        )
        base.update(kw)
        return NodeProgram(**base)


def test_params_file_arguments():
    argv = ["calibrator", "--ros-args", "--params-file", "a.yaml", "-p", "x:=1",
            "--params-file=/abs/b.yaml", "--params-file"]
    assert params_file_arguments(argv) == ["a.yaml", "/abs/b.yaml"]


def test_start_failure_message_is_one_line_naming_the_missing_file(tmp_path):
    exc = RuntimeError("failed to initialize rcl: Couldn't parse params file: 'Error opening "
                       "YAML file, at ./src/parser.c:271'\n, at ./src/rcl/arguments.c:406")
    (tmp_path / "there.yaml").write_text("/**: {ros__parameters: {}}\n")
    argv = ["--ros-args", "--params-file", "config/mobile_rig_mocap.yaml",
            "--params-file", "there.yaml", "--params-file", "/nowhere/x.yaml"]
    msg = start_failure_message(exc, argv, cwd=str(tmp_path))
    assert "\n" not in msg
    assert msg.startswith("cannot start ROS: failed to initialize rcl: Couldn't parse params file")
    assert (f"parameter file 'config/mobile_rig_mocap.yaml' not found (relative paths are taken "
            f"from the current directory {tmp_path};") in msg
    assert "$(ros2 pkg prefix --share rwhec_ros)/config/" in msg
    assert "there.yaml" not in msg  # readable: not blamed
    assert "parameter file '/nowhere/x.yaml' not found" in msg
    assert "/nowhere/x.yaml' not found (" not in msg  # absolute: no hint about the cwd


def test_init_failure_is_one_line_and_exit_1(capsys):
    rec = Recorder()

    def init():
        raise RuntimeError("failed to initialize rcl: Couldn't parse params file\n at x.c:1")

    code = run_node_program(rec.program(
        init=init, argv=["calibrator", "--ros-args", "--params-file", "missing.yaml"]))
    assert code == EXIT_START_FAILED and rec.calls == []
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("[FATAL] [calibrator]: cannot start ROS: failed to initialize rcl")
    assert "parameter file 'missing.yaml' not found" in err


def test_invalid_configuration_exit_2_and_shutdown():
    rec = Recorder()

    def build():
        raise ValueError("noise.sigma: must be > 0, got -1.0")

    assert run_node_program(rec.program(build=build)) == EXIT_BAD_CONFIG
    assert rec.fatal == ["invalid configuration: noise.sigma: must be > 0, got -1.0"]
    assert rec.calls == ["init", "shutdown"]  # no node to stop, but ROS is shut down


@pytest.mark.parametrize("stop", [KeyboardInterrupt, ConnectionAbortedError])
def test_stop_by_interrupt_or_external_shutdown_cleans_up_in_order(stop):
    rec = Recorder()

    def spin(built):
        rec.calls.append("spin")
        raise stop()

    code = run_node_program(rec.program(spin=spin, quiet_exceptions=(ConnectionAbortedError,)))
    assert code == EXIT_OK
    assert rec.calls == ["init", "build", "spin", "stop", "destroy", "shutdown"]


def test_failing_clean_up_step_is_reported_and_the_rest_still_runs():
    rec = Recorder()

    def broken():
        raise RuntimeError("publisher's context is invalid")

    code = run_node_program(rec.program(
        stop_steps=lambda built: [broken, lambda: rec.calls.append("destroy")]))
    assert code == EXIT_OK
    assert rec.calls == ["init", "build", "spin", "destroy", "shutdown"]
    assert rec.fatal == ["during shutdown: RuntimeError: publisher's context is invalid"]


def test_two_sigints_in_process_give_one_quiet_stop():
    """Real signals to this process: the first stops the spin, the second (during the clean-up)
    is ignored; afterwards (restore_signals) the previous handlers are back."""
    rec = Recorder()
    previous = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)

    def spin(built):
        rec.calls.append("spin")
        os.kill(os.getpid(), signal.SIGINT)
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:  # the handler raises KeyboardInterrupt in here
            time.sleep(0.01)
        rec.calls.append("spin was not interrupted")

    def slow_destroy():
        os.kill(os.getpid(), signal.SIGINT)  # the forwarded SIGINT of ros2 launch
        time.sleep(0.05)
        rec.calls.append("destroy")

    program = rec.program(spin=spin, stop_steps=lambda b: [slow_destroy])
    code = run_node_program(program, restore_signals=True)
    assert code == EXIT_OK and program.stop.is_set()
    assert rec.calls == ["init", "build", "spin", "destroy", "shutdown"]
    assert rec.fatal == []
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == previous


def test_without_restore_the_signals_stay_ignored_after_the_program():
    """The console scripts: the process exits right after; a late Ctrl-C must find SIGINT
    ignored, not the interpreter's default handler (issue 39: exit 130 / -2)."""
    previous = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    try:
        assert run_node_program(Recorder().program()) == EXIT_OK
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
        assert signal.getsignal(signal.SIGTERM) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous[0])
        signal.signal(signal.SIGTERM, previous[1])


def test_a_spin_that_watches_stop_gets_no_exception():
    """``interrupt=False`` (rclpy_main): the first signal only sets ``stop``; the spin returns
    by itself, nothing is raised in the middle of it."""
    rec = Recorder()
    stop = threading.Event()

    def spin(built):
        rec.calls.append("spin")
        os.kill(os.getpid(), signal.SIGTERM)
        deadline = time.monotonic() + 5.0
        while not stop.is_set() and time.monotonic() < deadline:
            time.sleep(0.01)
        rec.calls.append("spin returned")

    code = run_node_program(rec.program(spin=spin, stop=stop, interrupt=False),
                            restore_signals=True)
    assert code == EXIT_OK
    assert rec.calls == ["init", "build", "spin", "spin returned", "stop", "destroy", "shutdown"]


SCRIPT = textwrap.dedent("""
    import sys, threading, time
    from rwhec_ros.ros.process import NodeProgram, run_node_program

    stop = threading.Event()

    def spin(built):
        print("spinning", flush=True)
        while not stop.is_set():  # as rclpy_main: spin_once until the first signal
            time.sleep(0.01)

    def slow(name):
        def step():
            time.sleep(0.4)  # a slow destroy_node: a second signal may arrive meanwhile
            print(name, flush=True)
        return step

    code = run_node_program(NodeProgram(
        name="fake", init=lambda: None, build=lambda: object(), spin=spin,
        stop_steps=lambda built: [slow("stopped"), slow("destroyed")],
        shutdown=lambda: print("shutdown", flush=True),
        fatal=lambda text: print("FATAL", text, flush=True), stop=stop, interrupt=False))
    time.sleep(float(sys.argv[1]))  # the interpreter's shutdown: late signals land here
    sys.exit(code)
""")


def run_script(signals, gaps, teardown_s=0.0):
    """Start SCRIPT, send ``signals`` with ``gaps`` [s] between them; (code, out, err)."""
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT, str(teardown_s)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stdout.readline().strip() == "spinning"
        for sig, gap in zip(signals, [0.0, *gaps]):
            time.sleep(gap)
            proc.send_signal(sig)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    return proc.returncode, out, err


@pytest.mark.parametrize("gap", [0.02, 0.05, 0.2, 0.3, 0.5, 1.0, 2.5])
def test_two_ctrl_c_at_any_spacing_exit_0_without_traceback(gap):
    """Issue 39: a second SIGINT about 0.3 s after the first killed the node. The clean-up here
    takes 0.8 s and the interpreter's shutdown 3 s: the second lands in one or the other."""
    code, out, err = run_script([signal.SIGINT, signal.SIGINT], [gap], teardown_s=3.0)
    assert code == 0, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert out.split() == ["stopped", "destroyed", "shutdown"]


@pytest.mark.parametrize("signals", [
    [signal.SIGTERM],
    [signal.SIGINT, signal.SIGINT, signal.SIGINT],
    [signal.SIGINT, signal.SIGTERM],  # launch escalates to SIGTERM
    [signal.SIGTERM, signal.SIGINT],
])
def test_sigterm_and_mixed_signals_exit_0_without_traceback(signals):
    code, out, err = run_script(signals, [0.1] * (len(signals) - 1), teardown_s=1.0)
    assert code == 0, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert out.split() == ["stopped", "destroyed", "shutdown"]


def test_a_program_stopped_before_it_started_starts_nothing():
    rec = Recorder()
    stop = threading.Event()
    stop.set()
    assert run_node_program(rec.program(stop=stop, interrupt=False),
                            restore_signals=True) == EXIT_OK
    assert rec.calls == []


def test_the_entry_module_takes_the_signals_before_the_heavy_imports():
    """The console scripts start in rwhec_ros.ros.entry, which imports neither rclpy nor the
    node (seconds of imports on a loaded machine: a Ctrl-C then must be quiet too)."""
    code = ("import sys; import rwhec_ros.ros.entry as e; "
            "print(sorted(m for m in ('rclpy', 'cv2', 'numpy', 'rwhec_ros.ros.node') "
            "if m in sys.modules))")
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


STARTING = textwrap.dedent("""
    import sys, time
    from rwhec_ros.ros import entry

    entry._take_signals()  # what the console scripts do first
    print("importing", flush=True)
    time.sleep(5.0)  # the imports of rclpy, OpenCV, ...: the signals land here
    print("started", flush=True)
""")


@pytest.mark.parametrize("signals", [[signal.SIGINT, signal.SIGINT], [signal.SIGTERM]])
def test_signals_while_starting_exit_0_at_once_without_traceback(signals):
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-c", STARTING], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stdout.readline().strip() == "importing"
        t0 = time.monotonic()
        for sig in signals:
            proc.send_signal(sig)
            time.sleep(0.1)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert time.monotonic() - t0 < 3.0  # at once, not after the rest of the start-up
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert out.split() == []


def test_wait_for_tasks_waits_for_the_executors_queued_callbacks():
    from types import SimpleNamespace

    from rwhec_ros.ros.process import wait_for_tasks

    done = threading.Event()
    task = SimpleNamespace(done=done.is_set)
    threading.Timer(0.2, done.set).start()
    t0 = time.monotonic()
    assert wait_for_tasks(SimpleNamespace(_futures=[task]), 5.0)
    assert 0.15 < time.monotonic() - t0 < 4.0
    stuck = SimpleNamespace(done=lambda: False)
    assert not wait_for_tasks(SimpleNamespace(_futures=[stuck]), 0.1)
    assert wait_for_tasks(object(), 0.1)  # no such attribute: nothing to wait for
