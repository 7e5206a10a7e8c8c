#!/usr/bin/env bash
# Install the Debian packages livedic needs for GenICam cameras (Aravis through
# GObject introspection) and make Debian's `gi` importable from a Python venv.
#
# Usage: scripts/install_system.sh [VENV]        (VENV defaults to .venv)
#
# Idempotent and non-interactive. Runs apt-get directly as root, through sudo
# otherwise; retries while another apt/dpkg holds the lock.
#
# How gi reaches the venv: Debian's python3-gi (PyGObject 3.42) is built for
# CPython 3.11, the same ABI as the project's pyenv 3.11, so a symlink from the
# venv's site-packages to /usr/lib/python3/dist-packages/gi works with no build.
# (Alternatives: a venv made with `/usr/bin/python3 -m venv --system-site-packages`,
# or `pip install "pygobject<3.51"` after installing libgirepository1.0-dev.)
set -euo pipefail

VENV="${1:-.venv}"
PACKAGES=(
    gir1.2-aravis-0.8   # Aravis 0.8 typelib + libaravis-0.8.so.0 (GigE Vision, USB3 Vision, Fake)
    python3-gi          # PyGObject built for Debian's CPython 3.11
    gir1.2-glib-2.0     # GLib/GObject typelibs used by gi
    aravis-tools        # arv-fake-gv-camera-0.8 (GigE Vision simulator), arv-viewer
    aravis-tools-cli    # arv-tool-0.8 (list cameras, read/write features)
)
DEBIAN_GI=/usr/lib/python3/dist-packages/gi
APT_RETRIES=12          # x (10 s apt lock timeout + 10 s pause) = 4 min for a busy dpkg lock

die() { echo "install_system.sh: error: $*" >&2; exit 1; }
say() { echo "install_system.sh: $*"; }

if [ -f /etc/debian_version ] && command -v apt-get >/dev/null 2>&1; then :; else
    die "this script needs Debian/Ubuntu with apt-get; install Aravis 0.8 + PyGObject by hand"
fi

if [ "$(id -u)" -eq 0 ]; then
    SUDO=()
elif command -v sudo >/dev/null 2>&1; then
    SUDO=(sudo)
else
    die "not root and sudo is not installed: run as root or install sudo"
fi

# apt-get with retries while the dpkg/apt lock is held by someone else.
apt_retry() {
    local attempt out rc
    for attempt in $(seq 1 "$APT_RETRIES"); do
        set +e
        out=$("${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get \
              -o DPkg::Lock::Timeout=10 "$@" 2>&1)
        rc=$?
        set -e
        if [ $rc -eq 0 ]; then
            printf '%s\n' "$out" | tail -n 3
            return 0
        fi
        if printf '%s' "$out" | grep -qiE 'could not get lock|unable to acquire|lock-frontend|is another process using it|dpkg was interrupted'; then
            if printf '%s' "$out" | grep -qi 'dpkg was interrupted'; then
                die "dpkg was interrupted; run 'dpkg --configure -a' as root, then retry"
            fi
            say "apt/dpkg is busy (attempt $attempt/$APT_RETRIES), retrying in 10 s"
            sleep 10
            continue
        fi
        printf '%s\n' "$out" >&2
        die "apt-get $* failed (exit $rc); see the output above"
    done
    die "apt/dpkg stayed locked for about $((APT_RETRIES * 20)) s; try again later"
}

missing=()
for p in "${PACKAGES[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
        missing+=("$p")
    fi
done
if [ ${#missing[@]} -gt 0 ]; then
    say "installing: ${missing[*]}"
    apt_retry update -q
    apt_retry install -y -q --no-install-recommends "${missing[@]}"
else
    say "Debian packages already installed: ${PACKAGES[*]}"
fi

# --- make Debian's gi importable from the venv ------------------------------------
[ -d "$DEBIAN_GI" ] || die "$DEBIAN_GI not found after installing python3-gi"
[ -x "$VENV/bin/python" ] || die "no Python at $VENV/bin/python: create the venv first (python -m venv $VENV)"

PYVER=$("$VENV/bin/python" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
if [ "$PYVER" != "3.11" ]; then
    die "venv Python is $PYVER but Debian's python3-gi is built for 3.11; use a 3.11 venv or pip install 'pygobject<3.51' (needs libgirepository1.0-dev libcairo2-dev)"
fi
SITE=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
[ -d "$SITE" ] || die "venv site-packages $SITE does not exist"

if [ -L "$SITE/gi" ] && [ "$(readlink "$SITE/gi")" = "$DEBIAN_GI" ]; then
    say "$SITE/gi already links to $DEBIAN_GI"
elif "$VENV/bin/python" -c 'import gi' 2>/dev/null && [ ! -L "$SITE/gi" ]; then
    say "gi already importable from $VENV (not a Debian link); leaving it"
else
    if [ -e "$SITE/gi" ] && [ ! -L "$SITE/gi" ]; then
        die "$SITE/gi exists and is not a link; remove it or keep it and drop this step"
    fi
    ln -sfn "$DEBIAN_GI" "$SITE/gi"
    say "linked $SITE/gi -> $DEBIAN_GI"
fi

# --- check the whole chain works ---------------------------------------------------
"$VENV/bin/python" - <<'EOF' || die "gi/Aravis import check failed from the venv (see above)"
import gi
gi.require_version("Aravis", "0.8")
from gi.repository import Aravis
Aravis.update_device_list()  # exercises libaravis, not just the typelib
print("install_system.sh: Aravis %s importable from the venv (PyGObject %s)"
      % (Aravis._version, gi.__version__))
EOF
