"""clm-studio warns when it listens beyond this machine, prints a URL that opens (IPv6 in brackets), and
refuses a --token it could not put in a URL."""

from __future__ import annotations

import pytest

from studio.address import exposure_warning, is_loopback, url_for
from studio.gate import check_token, new_token
from studio.serve import main


@pytest.mark.parametrize("host", ["127.0.0.1", "localhost", "::1", "127.1.2.3", "[::1]"])
def test_loopback_hosts_print_no_warning(host):
    assert is_loopback(host) and exposure_warning(host, 8080) is None


@pytest.mark.parametrize("host", ["0.0.0.0", "::", "192.168.1.5", "example.org"])
def test_other_hosts_warn_on_one_line_that_anyone_can_drive_it(host):
    w = exposure_warning(host, 8097)
    assert w is not None and "\n" not in w
    assert w.startswith("clm-studio: warning:") and "no authentication" in w and "8097" in w and "--token" in w
    t = exposure_warning(host, 8097, token=True)
    assert t is not None and "\n" not in t and "token" in t and "no authentication" not in t


def test_urls_open_in_a_browser():
    assert url_for("127.0.0.1", 8080) == "http://localhost:8080"
    assert url_for("::", 8097) == "http://[::]:8097"
    assert url_for("::1", 8097) == "http://[::1]:8097"
    assert url_for("0.0.0.0", 8097) == "http://0.0.0.0:8097"
    assert url_for("::", 8097, "abcdefgh") == "http://[::]:8097/?token=abcdefgh"


def test_random_tokens_are_usable_and_distinct():
    tokens = {new_token() for _ in range(50)}
    assert len(tokens) == 50 and all(check_token(t) == t for t in tokens)


@pytest.mark.parametrize("token", ["short", "x" * 129, "has space", "a&b=cdefgh", "ümlautsxx", "a/b/c/d/e"])
def test_a_token_that_cannot_travel_in_a_url_is_refused_in_one_line(token, capsys):
    assert main(["--token", token, "--port", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("clm-studio: error: --token: expected 8 to 128 characters")


@pytest.mark.parametrize(("argv", "says"), [
    (["--port", "70000"], "--port: expected a port number 0-65535, got '70000'"),
    (["--port", "-1"], "--port: expected a port number 0-65535"),
    (["--port", "x"], "--port: expected a port number"),
    (["--bogus"], "unrecognized arguments: --bogus"),
    (["--host", "no.such.host.invalid", "--port", "0"], "--host no.such.host.invalid --port 0: cannot listen there"),
])
def test_a_bad_address_is_one_error_line_and_exit_2(argv, says, capsys):
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse's refusals exit from inside
        status = exc.code
    assert status == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("clm-studio: error: ") and says in err[0], err
