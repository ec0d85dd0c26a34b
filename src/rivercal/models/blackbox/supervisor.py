"""The supervisor of one black-box run: starts the program, and stops it and everything it started.

rivercal does not start the external program itself but this small script (run by path with ``python
-I -S``: the standard library only, nothing of rivercal is imported, about 10 ms), which starts the
program and stays between the two for the whole run:

- on Linux it is a *child subreaper* (``prctl(PR_SET_CHILD_SUBREAPER)``): whatever the program starts —
  children, grandchildren in a session of their own, daemons that fork twice — stays below it in the
  process tree, since an orphan is handed to the nearest subreaper, not to process 1;
- it ends with rivercal however rivercal ends (SIGKILL included): the kernel sends it SIGTERM when the
  rivercal thread that started it ends (``prctl(PR_SET_PDEATHSIG)``), and the program gets SIGKILL when
  the supervisor ends;
- on SIGTERM, SIGINT or SIGHUP (a timeout, an interrupted rivercal, rivercal's end), and when the program
  exits (successful or not), it kills every process below it (walking ``/proc`` until none is left) and
  reaps them; so nothing the program started outlives its run.

It reports through a pipe rivercal passes (its file descriptor is the second argument) one line:
``exit N`` (the program's exit status), ``signal N`` (the program ended by a signal), ``stopped`` (the
supervisor was told to stop) or ``error ERRNO`` (the program could not be started). Elsewhere than on Linux
(no prctl, no /proc) it kills the program's process group only.

Usage: ``python -I -S supervisor.py PARENT_PID STATUS_FD -- ARGV...``
"""

import os
import signal
import sys
import time

_LINUX = sys.platform.startswith("linux")
_PR_SET_PDEATHSIG = 1
_PR_SET_CHILD_SUBREAPER = 36
_STOP_SIGNALS = (signal.SIGTERM, signal.SIGINT, signal.SIGHUP)
#: Whether this process became a child subreaper (every descendant then stays below it).
_SUBREAPER = False


class _Stop(Exception):
    """Raised by the signal handler to leave the wait for the program."""


def _prctl(option, value):
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    return libc.prctl(option, value, 0, 0, 0) == 0


def _below(root):
    """Pids of the live processes below ``root`` (its children, theirs, ...), from /proc."""
    parent_of = {}
    try:
        entries = os.listdir("/proc")
    except OSError:
        return set()
    for name in entries:
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat", "rb") as f:
                fields = f.read().rpartition(b")")[2].split()
        except OSError:
            continue
        if fields and fields[0] not in (b"Z", b"X"):
            parent_of[int(name)] = int(fields[1])
    found, frontier = set(), {root}
    while frontier:
        frontier = {p for p, parent in parent_of.items() if parent in frontier} - found
        found |= frontier
    return found


def _reap():
    """Collect every ended child (the program, and orphans handed to this subreaper); their statuses."""
    ended = {}
    while True:
        try:
            pid, status = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return ended
        if pid == 0:
            return ended
        ended[pid] = status


def _kill_all(program, deadline_s=30.0):
    """SIGKILL every process below this one until none is left (or the deadline passes); reap them."""
    ended = {}
    stop = time.monotonic() + deadline_s
    while True:
        ended.update(_reap())
        if _SUBREAPER and not _has_children():  # a subreaper without children has no descendants at all
            return ended
        if _LINUX:
            left = _below(os.getpid())
        else:  # no /proc: the program's process group is what can be reached
            left = set()
            try:
                os.killpg(program, signal.SIGKILL)
            except OSError:
                pass
        for pid in left:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        ended.update(_reap())
        if not left or time.monotonic() > stop:
            return ended
        time.sleep(0.005)


def _has_children():
    """Whether this process has a child, live or ended but not yet reaped."""
    try:
        os.waitid(os.P_ALL, 0, os.WEXITED | os.WNOHANG | os.WNOWAIT)
    except ChildProcessError:
        return False
    return True


def _report(fd, text):
    try:
        os.write(fd, (text + "\n").encode())
    except OSError:
        pass


def main(args):
    """Start the program, wait for it (or a stop), stop everything below, report; the exit status (0)."""
    parent, fd, argv = int(args[0]), int(args[1]), args[3:]

    def stop(signum, frame):
        raise _Stop

    for sig in _STOP_SIGNALS:
        signal.signal(sig, stop)
    global _SUBREAPER
    if _LINUX:
        _SUBREAPER = _prctl(_PR_SET_CHILD_SUBREAPER, 1)
        _prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM))
    if os.getppid() != parent:  # rivercal ended before the parent-death signal was armed
        _report(fd, "stopped")
        return 0
    errors_r, errors_w = os.pipe()  # both close on exec: the program never sees them
    program = 0
    status = None
    try:
        signal.pthread_sigmask(signal.SIG_BLOCK, _STOP_SIGNALS)  # no stop between fork and the handlers' reset
        program = os.fork()
        if program == 0:
            try:
                for sig in _STOP_SIGNALS:
                    signal.signal(sig, signal.SIG_DFL)
                signal.pthread_sigmask(signal.SIG_UNBLOCK, _STOP_SIGNALS)
                if _LINUX:
                    _prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL))
                os.setsid()
                os.close(errors_r)
                os.close(fd)
                os.execvp(argv[0], argv)
            except OSError as exc:
                os.write(errors_w, str(exc.errno or 22).encode())
            except BaseException:  # an argument the system refuses (ValueError): "invalid argument"
                os.write(errors_w, b"22")
            finally:
                os._exit(127)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, _STOP_SIGNALS)
        os.close(errors_w)
        failed = b""
        while chunk := os.read(errors_r, 64):  # empty at once when the program was started (close on exec)
            failed += chunk
        os.close(errors_r)
        if failed:
            status = f"error {int(failed)}"
            return 0
        while True:
            pid, code = os.waitpid(-1, 0)
            if pid == program:
                break
        status = f"exit {os.waitstatus_to_exitcode(code)}" if os.WIFEXITED(code) else f"signal {os.WTERMSIG(code)}"
    except _Stop:
        status = "stopped"
    finally:
        for sig in _STOP_SIGNALS:  # finish the clean-up whatever arrives now
            signal.signal(sig, signal.SIG_IGN)
        if program > 0:
            ended = _kill_all(program)
            if status is None and program in ended:  # it ended as the stop came
                status = "stopped"
        _report(fd, status or "stopped")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
