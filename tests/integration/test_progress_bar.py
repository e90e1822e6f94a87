"""The progress bar on a terminal prints formatted numbers (issue 35, row 7): under a
pseudo-terminal that reports no width, tqdm used to drop the bar format and print the raw floats
(``16.666783564905753/133.33426851924602``)."""
import fcntl
import os
import pty
import re
import struct
import sys
import termios

import pytest

from conftest import ROOT

CHILD = r'''
import sys
from millimpact.integration.integrators import terminal_bar
bar = terminal_bar("full", 133.33426851924602, "us", sys.stderr)
for _ in range(3):
    bar.update(16.666783564905753)
bar.close()
'''


def run_under_pty(columns: int) -> str:
    """The child's terminal output, its pseudo-terminal ``columns`` wide (0: no size set)."""
    pid, fd = pty.fork()
    if pid == 0:   # the child: stdin/stdout/stderr are the pseudo-terminal
        try:
            os.chdir(ROOT)
            os.execv(sys.executable, [sys.executable, "-c", CHILD])
        finally:
            os._exit(127)
    if columns:
        fcntl.ioctl(fd, termios.TIOCSWINSZ, struct.pack("HHHH", 24, columns, 0, 0))
    out = b""
    while True:
        try:
            chunk = os.read(fd, 4096)
        except OSError:      # EIO: the child closed the terminal
            break
        if not chunk:
            break
        out += chunk
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0, out.decode(errors="replace")
    return out.decode(errors="replace")


@pytest.mark.parametrize("columns", [0, 100])
def test_the_terminal_bar_shows_three_significant_digits(columns):
    text = run_under_pty(columns)
    assert "50/133 us simulated" in text, text                     # 3 x 16.67 of 133.3 us
    assert not re.search(r"\d+\.\d{4,}", text), text               # no raw float anywhere
