"""The unit tier's guard (tests/unit/conftest.py): starting a process, a server or a connection fails loudly."""

from __future__ import annotations

import multiprocessing
import os
import socket
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor

import pytest

from tests.unit.conftest import UnitTierViolation


def test_a_subprocess_is_refused_with_where_the_test_belongs() -> None:
    with pytest.raises(UnitTierViolation, match=r"start a subprocess.*tests/integration.*tests/e2e"):
        subprocess.run([sys.executable, "-c", "pass"], check=True)
    with pytest.raises(UnitTierViolation):
        os.system("true")


def test_processes_and_process_pools_are_refused() -> None:
    with pytest.raises(UnitTierViolation, match="start a process"):
        multiprocessing.get_context("spawn").Process(target=print).start()
    with pytest.raises(UnitTierViolation), ProcessPoolExecutor(max_workers=1) as pool:
        pool.submit(print).result()


def test_servers_and_connections_are_refused_but_a_socket_pair_is_not() -> None:
    with socket.socket() as server, pytest.raises(UnitTierViolation, match="bind a socket"):
        server.bind(("127.0.0.1", 0))
    with socket.socket() as client, pytest.raises(UnitTierViolation, match="connect a socket"):
        client.connect(("127.0.0.1", 9))
    left, right = socket.socketpair()  # threads (asyncio's own wake-up) may talk through a pair
    with left, right:
        left.sendall(b"x")
        assert right.recv(1) == b"x"
