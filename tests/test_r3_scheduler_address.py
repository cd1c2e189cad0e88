"""Scheduler addresses an outsider types by mistake: a port with a path after it, the dashboard's URL.

`--scheduler tcp://HOST:8786/` gave "invalid literal for int() with base 10: '8786/'" (Python's words for a
failed int()), and the dashboard's `http://HOST:8787/status` only "unknown scheme 'http'"; each is one line that
says what is wrong and what the address should be. No cluster is needed: the address is refused before any
connection.
"""

from __future__ import annotations

import contextlib
import io

import pytest

from gearctl import InputError
from gearctl.cli import main
from gearctl.parallel import probe_scheduler


@pytest.mark.parametrize(("address", "port"), [("tcp://127.0.0.1:8786/", "8786/"),
                                               ("tcp://127.0.0.1:8786/status", "8786/status"),
                                               ("tcp://127.0.0.1:8.786e3", "8.786e3"),
                                               ("tls://[::1]:port", "port")])
def test_a_port_that_is_no_whole_number_is_named(address: str, port: str) -> None:
    with pytest.raises(InputError, match=rf"the port '{port}' is not a whole number 1\.\.65535") as e:
        probe_scheduler(address, timeout=1.0)
    assert "invalid literal" not in str(e.value) and e.value.field == "scheduler"


@pytest.mark.parametrize("address", ["http://127.0.0.1:8787/status", "https://dask.example.org:8787"])
def test_the_dashboards_url_is_told_apart_from_the_schedulers_address(address: str) -> None:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = main(["sweep", "--runs", "2", "--duration", "0.2", "--quiet", "--scheduler", address])
    assert rc == 2 and err.getvalue().count("\n") == 1, err.getvalue()
    assert f"cannot reach the Dask scheduler at {address}: unknown scheme" in err.getvalue()
    assert "the Dask dashboard's; the scheduler itself listens on tcp://HOST:PORT" in err.getvalue()
