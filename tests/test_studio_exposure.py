"""clm-studio warns when it listens beyond this machine, and prints a URL that opens (IPv6 in brackets)."""

from __future__ import annotations

import pytest

from studio.app import url_for
from studio.serve import exposure_warning, is_loopback


@pytest.mark.parametrize("host", ["127.0.0.1", "localhost", "::1", "127.1.2.3", "[::1]"])
def test_loopback_hosts_print_no_warning(host):
    assert is_loopback(host) and exposure_warning(host, 8080) is None


@pytest.mark.parametrize("host", ["0.0.0.0", "::", "192.168.1.5", "example.org"])
def test_other_hosts_warn_on_one_line_that_anyone_can_drive_it(host):
    w = exposure_warning(host, 8097)
    assert w is not None and "\n" not in w
    assert w.startswith("clm-studio: warning:") and "no authentication" in w and "8097" in w


def test_urls_open_in_a_browser():
    assert url_for("127.0.0.1", 8080) == "http://localhost:8080"
    assert url_for("::", 8097) == "http://[::]:8097"
    assert url_for("::1", 8097) == "http://[::1]:8097"
    assert url_for("0.0.0.0", 8097) == "http://0.0.0.0:8097"
