#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Install the Debian packages gearsim needs (idempotent: does nothing when
# everything is present). Runs as root or through sudo.
set -euo pipefail
pkgs=(build-essential pkgconf meson ninja-build
      openmpi-bin libopenmpi-dev libzmq3-dev libjson-c-dev
      libhdf5-openmpi-dev hdf5-tools libsuitesparse-dev liblapacke-dev libopenblas-dev
      libcmocka-dev python3 python3-zmq python3-h5py python3-numpy python3-jsonschema
      python3-matplotlib python3-cvxopt
      clang libclang-rt-14-dev  # clang + libFuzzer: tests/fuzz, deploy/fuzz.sh
      jupyter-nbconvert python3-ipykernel python3-nbclient python3-nbformat  # the example notebook
      python3-pip python3-setuptools python3-wheel python3-venv  # pip install ./clients/python in a venv
      man-db  # man gearsimd, man gearctl
      python3-sphinx python3-myst-parser furo  # the manual (docs/conf.py, ninja -C build manual, test manual)
      slurmctld slurmd slurm-client munge  # test_slurm: a one-node Slurm of the test's own
      git iproute2 util-linux)  # test_install: a fresh clone; ss; test_two_hosts: ip netns, unshare
# The FE reference (tests/reference/) and bench_reference.py: no test needs
# them, so they come only with --reference.
if [ "${1:-}" = "--reference" ]; then
  pkgs+=(gmsh calculix-ccx)
fi
# docs/tools/screenshots.py (the manual's page screenshots, headless): no test
# needs a browser, so it comes only with --screenshots.
if [ "${1:-}" = "--screenshots" ]; then
  pkgs+=(chromium)
fi
# tests/integration/test_minimal_root.py (GEARSIM_LONG=1): a minimal Debian
# root to run the README in, so debootstrap comes only with --minimal-root.
if [ "${1:-}" = "--minimal-root" ]; then
  pkgs+=(debootstrap)
fi
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "Debian packages: all ${#pkgs[@]} present"
  exit 0
fi
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
echo "installing ${#missing[@]} Debian package(s) and what they depend on: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
echo "apt-get update (the package lists)"
$SUDO apt-get update -qq
# apt's own lines, shortened to one per package and step with a count:
# "downloading (k/N)", "unpacking (k/N)", "setting up (k/N)".
$SUDO apt-get install -y --no-install-recommends -o Dpkg::Use-Pty=0 "${missing[@]}" 2>&1 | awk '
  /newly installed/ {
    n = $0; sub(/ newly installed.*/, "", n); sub(/.* /, "", n); total = n + 0
    print "  apt: " $0; fflush(); next }
  /^Need to get / { print "  apt: " $0; fflush(); next }
  /^Get:[0-9]+ / { g++; printf "  downloading (%d/%d) %s\n", g, total, $5; fflush(); next }
  /^Unpacking / { u++; printf "  unpacking (%d/%d) %s\n", u, total, $2; fflush(); next }
  /^Setting up / { k++; printf "  setting up (%d/%d) %s\n", k, total, $3; fflush(); next }
  /^(E|W): / { print; fflush() }'
echo "Debian packages installed"
