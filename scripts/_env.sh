# Sourced by scripts/studio and scripts/test: a project virtualenv in .venv with the package installed.
# Idempotent and fast on a second run: pip runs only when pyproject.toml (or the extra) changed.

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
export PIP_DISABLE_PIP_VERSION_CHECK=1 PIP_NO_INPUT=1
# numba caches compiled kernels next to the sources by default; keep them in the venv instead.
export NUMBA_CACHE_DIR="${NUMBA_CACHE_DIR:-$VENV/numba-cache}"

say() { printf '\n==> %s\n' "$*"; }

# Run a command as root: directly, through sudo, or fail with a hint.
as_root() {
    if [ "$(id -u)" -eq 0 ]; then
        "$@"
    elif command -v sudo >/dev/null 2>&1; then
        sudo "$@"
    else
        echo "need root for: $*" >&2
        return 1
    fi
}

APT_UPDATED=0
apt_install() {
    if [ "$APT_UPDATED" -eq 0 ]; then
        as_root env DEBIAN_FRONTEND=noninteractive apt-get update -q
        APT_UPDATED=1
    fi
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -q "$@"
}

# ensure_venv EXTRA: create .venv with Python 3.11 and pip install -e ".[EXTRA]" (or "." for no extra).
ensure_venv() {
    local extra="${1:-}" spec="." hash installed
    [ -n "$extra" ] && spec=".[$extra]"
    if ! "$VENV/bin/python" -c 'import sys; assert sys.version_info >= (3, 11)' 2>/dev/null; then
        local py
        py="$(command -v python3.11 || command -v python3 || true)"
        if [ -z "$py" ] || ! "$py" -c 'import sys; assert sys.version_info >= (3, 11)' 2>/dev/null; then
            echo "Python 3.11 or newer is needed (Debian: apt-get install python3.11)" >&2
            return 1
        fi
        say "creating $VENV with $("$py" --version)"
        rm -rf "$VENV"
        if ! "$py" -m venv "$VENV" 2>/dev/null; then
            # Debian ships venv's pip bootstrap separately.
            rm -rf "$VENV"
            apt_install python3-venv
            "$py" -m venv "$VENV"
        fi
    fi
    hash="$(sha256sum < "$ROOT/pyproject.toml" | cut -c1-16)"
    installed="$(cat "$VENV/.installed" 2>/dev/null || true)"
    # An install with an extra also serves the plain one.
    if [ "$installed" != "$hash $spec" ] && { [ "$spec" != "." ] || [ "${installed%% *}" != "$hash" ]; }; then
        say "installing clm-studio $spec into .venv"
        (cd "$ROOT" && "$VENV/bin/python" -m pip install -q -e "$spec")
        echo "$hash $spec" > "$VENV/.installed"
    fi
    export PATH="$VENV/bin:$PATH"
    export VIRTUAL_ENV="$VENV"
}
