"""The unit tier's rule, enforced: a unit test starts no process, no server and touches no network.

``make check`` runs this tier alone as the developer's quick loop, without chromium, PostgreSQL or any other
system package, so a test here must not start a subprocess (the CLI as a command, a black-box model, initdb),
a process pool, a Dask cluster (its workers are processes, its scheduler and dashboard servers), a browser, or
open a network socket. While a unit test and its fixtures are set up and while it runs, each of those fails at
once with a message that names what was started and where such a test belongs (``tests/integration`` or
``tests/e2e``). In-process work (the CLI through its runner, threads, files in ``tmp_path``) is allowed.
"""

from __future__ import annotations

import contextlib
import multiprocessing.process
import multiprocessing.util
import os
import socket
import subprocess
from collections.abc import Iterator

import pytest

#: Socket families that reach a server or a network.
_NETWORK_FAMILIES = {socket.AF_INET, socket.AF_INET6, socket.AF_UNIX}

_WHERE = ("tests/unit is the tier `make check` runs with no process, no server and no network; move this test to "
          "tests/integration (processes, servers, several components) or tests/e2e (the CLI as a command, the "
          "browser), or keep its work in this process")


#: Marks an attribute a class inherits (restored by deleting the replacement).
_INHERITED = object()


class UnitTierViolation(AssertionError):
    """A unit test started a process, a server or a network connection."""


def _refuse(what: str):
    def refused(*args, **kwargs):
        raise UnitTierViolation(f"a unit test must not {what}: {_WHERE}")

    return refused


def _guarded_socket(name: str, original):
    def call(self: socket.socket, *args, **kwargs):
        if self.family in _NETWORK_FAMILIES:
            address = args[0] if args else kwargs.get("address")
            raise UnitTierViolation(f"a unit test must not {name} a socket ({address!r}): {_WHERE}")
        return original(self, *args, **kwargs)

    return call


def _replacements() -> list[tuple[object, str, object]]:
    found: list[tuple[object, str, object]] = [
        (subprocess.Popen, "_execute_child", _refuse("start a subprocess")),
        (multiprocessing.process.BaseProcess, "start",
         _refuse("start a process (multiprocessing, a process pool, a Dask worker)")),
        (multiprocessing.util, "spawnv_passfds", _refuse("spawn a process")),
    ]
    for name in ("fork", "forkpty", "posix_spawn", "posix_spawnp", "system", "execv", "execve"):
        if hasattr(os, name):
            found.append((os, name, _refuse(f"call os.{name}")))
    for name in ("bind", "connect", "connect_ex"):
        found.append((socket.socket, name, _guarded_socket(name, getattr(socket.socket, name))))
    return found


@contextlib.contextmanager
def _no_process_server_or_network() -> Iterator[None]:
    replacements = _replacements()
    saved = [(owner, name, vars(owner).get(name, _INHERITED)) for owner, name, _ in replacements]
    try:
        for owner, name, replacement in replacements:
            setattr(owner, name, replacement)
        yield
    finally:
        for owner, name, original in saved:
            if original is _INHERITED:
                delattr(owner, name)
            else:
                setattr(owner, name, original)


# The fixtures' setup is guarded too (a session fixture that starts a server for a unit test is caught where it
# starts), their teardown is not: a worker may end a fixture an integration test made after its last unit test.
@pytest.hookimpl(wrapper=True)
def pytest_runtest_setup(item: pytest.Item):
    with _no_process_server_or_network():
        return (yield)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item):
    with _no_process_server_or_network():
        return (yield)
