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
      python3-pip python3-setuptools python3-wheel  # pip install ./clients/python (test_install)
      slurmctld slurmd slurm-client munge  # test_slurm: a one-node Slurm of the test's own
      iproute2 util-linux)  # test_two_hosts: ip netns, ss, unshare
# The FE reference (tests/reference/) and bench_reference.py: no test needs
# them, so they come only with --reference.
if [ "${1:-}" = "--reference" ]; then
  pkgs+=(gmsh calculix-ccx)
fi
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
echo "installing: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
