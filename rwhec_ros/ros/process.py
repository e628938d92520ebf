"""How the node programs start and stop.

:func:`run_node_program` takes the rclpy calls as arguments, so that it is tested without ROS;
:func:`rclpy_main` passes rclpy's (imported there, lazily) for a node spun by a
``MultiThreadedExecutor``.

What a ROS user expects, and what :func:`run_node_program` does for both console scripts
(``calibrator``, ``rwhec_demo_sim``):

* **start-up errors in one line.** ``rclpy.init`` raises ``RCLError`` (a ``RuntimeError``) before
  any node exists, e.g. ``Couldn't parse params file`` for a ``--params-file`` that cannot be
  read; the program prints one line naming the file (:func:`start_failure_message`) and exits
  with :data:`EXIT_START_FAILED`. An invalid configuration (``ValueError`` naming the parameter)
  exits with :data:`EXIT_BAD_CONFIG`.
* **Ctrl-C and SIGTERM are quiet, under ``ros2 run`` and ``ros2 launch``, exit code 0.**
  ``ros2 launch`` delivers SIGINT to each child twice (once from the terminal's process group,
  once forwarded by launch), at any spacing; it escalates to SIGTERM after 5 s. The program owns
  both signals: :func:`rclpy_main` starts rclpy *without* its signal handlers
  (``SignalHandlerOptions.NO``: rclpy's SIGTERM handler would shut the context down at once,
  under the feet of the worker threads, issue 39), and :func:`install_stop_handlers` makes the
  first SIGINT or SIGTERM ask the program to stop (``NodeProgram.stop``, and
  ``KeyboardInterrupt`` in the main thread unless the program's spin watches ``stop``) and
  ignore every later one *until the process exits*. The previous handlers are not restored
  (only with ``restore_signals``, for in-process callers): a second Ctrl-C 0.3 s after the first
  used to land in the interpreter's shutdown after the old handler was back and kill the node
  (exit code -2 under launch, 254 under ``ros2 run``). The clean-up runs step by step, each step
  guarded, so nothing can interrupt ``destroy_node()`` or skip ``rclpy.try_shutdown()``.
* **Activity stops before destruction.** The main thread stops spinning first (no callback
  starts any more), then the clean-up steps a node gives (timers cancelled, worker threads
  stopped and joined, ``executor.shutdown(timeout)`` waiting for running callbacks) run before
  ``destroy_node()`` and ``try_shutdown()``, so no worker or callback uses a destroyed publisher
  or an invalid context.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "EXIT_OK",
    "EXIT_START_FAILED",
    "EXIT_BAD_CONFIG",
    "NodeProgram",
    "run_node_program",
    "rclpy_main",
    "params_file_arguments",
    "start_failure_message",
    "install_stop_handlers",
    "wait_for_tasks",
    "signals_ignored",
    "STOP_SIGNALS",
]

EXIT_OK = 0
EXIT_START_FAILED = 1
EXIT_BAD_CONFIG = 2

#: The signals that stop a node program.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
#: Longest wait [s] of one ``spin_once`` of :func:`rclpy_main`: how soon a stop request is seen.
SPIN_POLL_S = 0.1


def params_file_arguments(argv: Sequence[str]) -> list[str]:
    """The paths given with ``--params-file PATH`` in ``argv`` (the ROS arguments)."""
    out = []
    args = [str(a) for a in argv]
    for i, a in enumerate(args):
        if a == "--params-file" and i + 1 < len(args):
            out.append(args[i + 1])
        elif a.startswith("--params-file="):
            out.append(a.split("=", 1)[1])
    return out


def _unreadable(path: str, cwd: str) -> str | None:
    """Why ``path`` cannot be read as a parameter file (None if it can)."""
    full = path if os.path.isabs(path) else os.path.join(cwd, path)
    if not os.path.exists(full):
        return "not found"
    if os.path.isdir(full):
        return "is a directory"
    if not os.access(full, os.R_OK):
        return "not readable"
    return None


def start_failure_message(exc: BaseException, argv: Sequence[str] = (),
                          cwd: str | None = None) -> str:
    """One line saying why ROS could not start: the first line of ``exc`` and, for every
    ``--params-file`` of ``argv`` that cannot be read, which one and where it was looked for,
    e.g. ``cannot start ROS: failed to initialize rcl: Couldn't parse params file: ...;
    parameter file 'config/x.yaml' not found (relative paths are taken from the current
    directory /home/me/ws; the package's own files are in $(ros2 pkg prefix --share
    rwhec_ros)/config/)``.
    """
    cwd = os.getcwd() if cwd is None else cwd
    text = " ".join(str(exc).split()) or type(exc).__name__
    parts = [f"cannot start ROS: {text}"]
    for path in params_file_arguments(argv):
        why = _unreadable(path, cwd)
        if why is None:
            continue
        hint = ""
        if not os.path.isabs(path):
            hint = (f" (relative paths are taken from the current directory {cwd}; the "
                    "package's own files are in $(ros2 pkg prefix --share rwhec_ros)/config/)")
        parts.append(f"parameter file {path!r} {why}{hint}")
    return "; ".join(parts)


def install_stop_handlers(stop: threading.Event, *, interrupt: bool = True) -> dict:
    """Make the first SIGINT or SIGTERM set ``stop`` (and raise ``KeyboardInterrupt`` in the
    main thread when ``interrupt``) and every later one of either be ignored; returns the
    previous handlers (empty when not called from the main thread, where Python cannot set
    handlers)."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    if stop.is_set():  # a signal came already (handlers installed earlier): ignore the rest
        return {s: signal.signal(s, signal.SIG_IGN) for s in STOP_SIGNALS}

    def first(signum, frame) -> None:
        for s in STOP_SIGNALS:
            signal.signal(s, signal.SIG_IGN)
        stop.set()
        if interrupt:
            raise KeyboardInterrupt

    return {s: signal.signal(s, first) for s in STOP_SIGNALS}


@contextmanager
def signals_ignored(*signums: int) -> Iterator[None]:
    """Ignore ``signums`` (default SIGINT and SIGTERM) inside the block, then restore the
    previous handlers. Outside the main thread nothing is changed."""
    signums = signums or (signal.SIGINT, signal.SIGTERM)
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.signal(s, signal.SIG_IGN) for s in signums}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler if handler is not None else signal.SIG_DFL)


@dataclass
class NodeProgram:
    """The calls of one node program (the node module passes rclpy's; tests pass fakes).

    Attributes
    ----------
    name : str
        Program name for messages (``calibrator``).
    init : callable
        ``rclpy.init(args=...)``.
    build : callable returning object
        Creates the node (and its executor); returns what ``spin`` and ``stop_steps`` take.
        ``ValueError`` means an invalid configuration.
    spin : callable(object)
        Blocks until shutdown (returns, or raises ``KeyboardInterrupt`` or one of
        ``quiet_exceptions``).
    stop_steps : callable(object) returning sequence of callables
        The clean-up, in order (stop timers and threads, shut the executor down, destroy the
        node); called with what ``build`` returned.
    shutdown : callable
        ``rclpy.try_shutdown``.
    fatal : callable(str)
        Reports a fatal error line (e.g. the node logger's ``fatal``).
    quiet_exceptions : tuple of exception types
        Also mean "stop" (``rclpy.executors.ExternalShutdownException``).
    argv : sequence of str
        The program's arguments (to name unreadable ``--params-file`` paths).
    stop : threading.Event
        Set by the first SIGINT or SIGTERM (:func:`install_stop_handlers`).
    interrupt : bool
        The first signal also raises ``KeyboardInterrupt`` in the main thread; False when
        ``spin`` returns by itself once ``stop`` is set (:func:`rclpy_main`: no exception in
        the middle of rclpy's executor).
    """

    name: str
    init: Callable[[], object]
    build: Callable[[], Any]
    spin: Callable[[Any], object]
    stop_steps: Callable[[Any], Sequence[Callable[[], object]]]
    shutdown: Callable[[], object]
    fatal: Callable[[str], object]
    quiet_exceptions: tuple[type[BaseException], ...] = ()
    argv: Sequence[str] = field(default_factory=lambda: list(sys.argv))
    stop: threading.Event = field(default_factory=threading.Event)
    interrupt: bool = True


def _run_quietly(step: Callable[[], object], program: NodeProgram) -> None:
    """Run one clean-up step; report (one line) anything it raises and go on."""
    try:
        step()
    except (Exception, KeyboardInterrupt) as exc:  # noqa: BLE001 - clean-up goes on
        try:
            program.fatal(f"during shutdown: {type(exc).__name__}: {exc}")
        except Exception:  # noqa: BLE001 - the logger may be gone with the context
            pass


def run_node_program(program: NodeProgram, *, restore_signals: bool = False) -> int:
    """Run ``program`` as described in the module docstring; returns the exit code
    (:data:`EXIT_OK`, :data:`EXIT_START_FAILED`, :data:`EXIT_BAD_CONFIG`).

    On return SIGINT and SIGTERM stay ignored (the process is about to exit: a late signal must
    not kill it in the interpreter's shutdown), unless ``restore_signals`` (in-process callers,
    tests) puts the previous handlers back."""
    previous = install_stop_handlers(program.stop, interrupt=program.interrupt)
    code = EXIT_OK
    built = None
    try:
        if program.stop.is_set():  # stopped while starting: nothing to start, nothing to stop
            return EXIT_OK
        try:
            program.init()
        except KeyboardInterrupt:
            return EXIT_OK
        except Exception as exc:  # noqa: BLE001 - RCLError is a RuntimeError; one line, no trace
            print(f"[FATAL] [{program.name}]: {start_failure_message(exc, program.argv)}",
                  file=sys.stderr)
            return EXIT_START_FAILED
        try:
            built = program.build()
            program.spin(built)
        except KeyboardInterrupt:
            pass
        except program.quiet_exceptions:
            pass
        except ValueError as exc:  # invalid configuration: names the parameter
            program.fatal(f"invalid configuration: {exc}")
            code = EXIT_BAD_CONFIG
        finally:
            with signals_ignored():
                steps: list[Callable[[], object]] = []
                if built is not None:
                    _run_quietly(lambda: steps.extend(program.stop_steps(built)), program)
                for step in [*steps, program.shutdown]:
                    _run_quietly(step, program)
    except KeyboardInterrupt:  # a first Ctrl-C in the instant after the clean-up
        pass
    finally:
        for s, handler in previous.items():
            if restore_signals:
                signal.signal(s, handler if handler is not None else signal.SIG_DFL)
            else:
                signal.signal(s, signal.SIG_IGN)
    return code


def wait_for_tasks(executor: Any, timeout_s: float) -> bool:
    """Wait up to ``timeout_s`` for the callbacks a ``MultiThreadedExecutor`` handed to its
    threads; True when none is left.

    Call it after the spin stopped and before ``executor.shutdown``: rclpy 7.1 (Jazzy)
    ``Executor.shutdown(timeout_sec)`` does not wait for them (it tests ``_is_shutdown`` right
    after setting it) and destroys its guard condition, which a task still queued then triggers:
    ``The following exception was never retrieved: cannot use Destroyable because destruction
    was requested`` on stderr at exit (seen under ``ros2 launch``). The executor keeps them in
    ``_futures`` (private; without it nothing is waited for)."""
    deadline = time.monotonic() + timeout_s
    for task in list(getattr(executor, "_futures", ())):
        while not task.done():
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.01)
    return True


def rclpy_main(name: str, make_node: Callable[[], Any], args: Sequence[str] | None = None, *,
               shutdown_timeout_s: float = 3.0) -> int:
    """Body of a node's console script: ``rclpy.init(args=args)`` without rclpy's signal
    handlers, ``make_node()`` spun by a ``MultiThreadedExecutor`` (``spin_once`` until the first
    SIGINT or SIGTERM, seen within :data:`SPIN_POLL_S`), then ``node.stop_activity()``, the
    callbacks handed to the executor's threads finished (:func:`wait_for_tasks`, up to
    ``shutdown_timeout_s``), ``executor.shutdown(shutdown_timeout_s)``, ``destroy_node()``
    and ``rclpy.try_shutdown()``, as :func:`run_node_program` runs them; returns the exit code.
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
    from rclpy.logging import get_logger
    from rclpy.signals import SignalHandlerOptions

    from ..allocator import retain_freed_memory

    retain_freed_memory()  # the live re-solve reuses its freed memory (see the module)

    def build():
        node = make_node()
        executor = MultiThreadedExecutor()
        executor.add_node(node)
        return node, executor

    def stop_steps(built):
        node, executor = built
        return [node.stop_activity,
                lambda: wait_for_tasks(executor, shutdown_timeout_s),
                lambda: executor.shutdown(timeout_sec=shutdown_timeout_s),
                node.destroy_node]

    stop = threading.Event()

    def spin(built) -> None:
        executor = built[1]
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=SPIN_POLL_S)

    return run_node_program(NodeProgram(
        name=name,
        init=lambda: rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO),
        build=build,
        spin=spin,
        stop=stop,
        interrupt=False,
        stop_steps=stop_steps,
        shutdown=rclpy.try_shutdown,
        fatal=get_logger(name).fatal,
        quiet_exceptions=(ExternalShutdownException,),
        argv=sys.argv if args is None else list(args),
    ))
