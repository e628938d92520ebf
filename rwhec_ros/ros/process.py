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
* **Ctrl-C is quiet, under ``ros2 run`` and ``ros2 launch``.** ``ros2 launch`` delivers SIGINT to
  each child twice (once from the terminal's process group, once forwarded by launch). The
  program installs, *before* ``rclpy.init`` (so that rclpy's own SIGINT handler, which wakes the
  executor, chains to it), a handler that turns the first SIGINT into ``KeyboardInterrupt`` and
  ignores every later one (:func:`install_first_sigint_handler`). The clean-up then runs with
  SIGINT and SIGTERM ignored (:func:`signals_ignored`), step by step, each step guarded, so a
  late signal can neither interrupt ``destroy_node()`` nor skip ``rclpy.try_shutdown()``; the
  exit code is 0.
* **Activity stops before destruction.** The clean-up steps a node gives (timers cancelled, worker
  threads joined, ``executor.shutdown(timeout)`` waiting for running callbacks) come before
  ``destroy_node()`` and ``try_shutdown()``, so no callback publishes on a destroyed publisher or
  an invalid context.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
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
    "install_first_sigint_handler",
    "signals_ignored",
]

EXIT_OK = 0
EXIT_START_FAILED = 1
EXIT_BAD_CONFIG = 2


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


def _first_sigint(signum, frame) -> None:
    """SIGINT handler: ignore every further SIGINT, then stop the program with
    ``KeyboardInterrupt`` (the second SIGINT of ``ros2 launch`` then cannot land in the
    clean-up)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    raise KeyboardInterrupt


def install_first_sigint_handler() -> Any:
    """Install :func:`_first_sigint` as the Python SIGINT handler; returns the previous handler
    (None when not called from the main thread, where Python cannot set handlers). Call it
    before ``rclpy.init``: rclpy's handler keeps the one it finds and calls it."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGINT, _first_sigint)


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


def _run_quietly(step: Callable[[], object], program: NodeProgram) -> None:
    """Run one clean-up step; report (one line) anything it raises and go on."""
    try:
        step()
    except (Exception, KeyboardInterrupt) as exc:  # noqa: BLE001 - clean-up goes on
        try:
            program.fatal(f"during shutdown: {type(exc).__name__}: {exc}")
        except Exception:  # noqa: BLE001 - the logger may be gone with the context
            pass


def run_node_program(program: NodeProgram) -> int:
    """Run ``program`` as described in the module docstring; returns the exit code
    (:data:`EXIT_OK`, :data:`EXIT_START_FAILED`, :data:`EXIT_BAD_CONFIG`)."""
    previous = install_first_sigint_handler()
    code = EXIT_OK
    built = None
    try:
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
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    return code


def rclpy_main(name: str, make_node: Callable[[], Any], args: Sequence[str] | None = None, *,
               shutdown_timeout_s: float = 3.0) -> int:
    """Body of a node's console script: ``rclpy.init(args=args)``, ``make_node()`` spun by a
    ``MultiThreadedExecutor``, then ``node.stop_activity()``,
    ``executor.shutdown(shutdown_timeout_s)`` (waits for running callbacks), ``destroy_node()``
    and ``rclpy.try_shutdown()``, as :func:`run_node_program` runs them; returns the exit code.
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
    from rclpy.logging import get_logger

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
                lambda: executor.shutdown(timeout_sec=shutdown_timeout_s),
                node.destroy_node]

    return run_node_program(NodeProgram(
        name=name,
        init=lambda: rclpy.init(args=args),
        build=build,
        spin=lambda built: built[1].spin(),
        stop_steps=stop_steps,
        shutdown=rclpy.try_shutdown,
        fatal=get_logger(name).fatal,
        quiet_exceptions=(ExternalShutdownException,),
        argv=sys.argv if args is None else list(args),
    ))
