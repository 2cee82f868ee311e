"""Where the studio listens and what it prints about it: the URL to open and the warning when it is exposed."""

from __future__ import annotations

import ipaddress


def is_loopback(host: str) -> bool:
    """True for this machine only: localhost, 127.0.0.0/8, ::1."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def url_for(host: str, port: int, token: str | None = None) -> str:
    """The address to open: ``localhost`` for loopback, IPv6 hosts in brackets (``http://[::]:8097``), the
    token (if any) as the ``token`` query parameter."""
    if host in ("127.0.0.1", "localhost"):
        host = "localhost"
    elif ":" in host and not host.startswith("["):
        host = f"[{host}]"
    return f"http://{host}:{port}" + ("" if token is None else f"/?token={token}")


def exposure_warning(host: str, port: int, token: bool = False) -> str | None:
    """The one-line warning printed when the studio listens beyond this machine (None on loopback)."""
    if is_loopback(host):
        return None
    if token:
        return (f"clm-studio: warning: listening on {host} port {port}: anyone who can reach this machine and has "
                f"the URL with its token can drive the studio and read and overwrite its session; the token "
                f"travels in plain HTTP. To keep it private, keep the default --host 127.0.0.1 and use an SSH "
                f"tunnel (ssh -L {port}:127.0.0.1:{port} ...).")
    return (f"clm-studio: warning: listening on {host} port {port}: anyone who can reach this machine can drive "
            f"the studio and read and overwrite its session; there is no authentication (add --token). For a "
            f"colleague, keep the default --host 127.0.0.1 and share it through an SSH tunnel "
            f"(ssh -L {port}:127.0.0.1:{port} ...).")
