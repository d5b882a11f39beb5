"""Fixtures shared by the gateway tests: a raw pty pair standing in for a base station's serial link."""
from __future__ import annotations

import os
import pty
import tty

import pytest


@pytest.fixture()
def pty_pair():
    master, slave = pty.openpty()
    tty.setraw(master)
    path = os.ttyname(slave)
    yield master, path
    for fd in (master, slave):
        try:
            os.close(fd)
        except OSError:
            pass
