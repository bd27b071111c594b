# SPDX-License-Identifier: MIT
# Environment for running gearsimd under Open MPI on one machine (sourced).
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1
export OMPI_MCA_btl_vader_single_copy_mechanism=none
export HDF5_USE_FILE_LOCKING=FALSE
# Open MPI on one machine (docs/RELIABILITY.md, "Threat model"): ranks talk
# through shared memory only (no TCP transport, which would listen on every
# interface), the runtime's out-of-band TCP is advertised on loopback only.
# Its listener still binds the wildcard address whatever the parameters say;
# the shim gearsim-loopback.so, preloaded into mpirun, turns those binds into
# loopback ones. GEARSIM_LOOPBACK_PRELOAD names it: the build's copy in a
# checkout, the installed one (PREFIX/<libdir>/gearsim) in an installed
# env.sh (meson install writes the path below).
export OMPI_MCA_btl=self,vader
export OMPI_MCA_oob_tcp_if_include=lo OMPI_MCA_btl_tcp_if_include=lo
_gs_root=$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")/.." 2>/dev/null && pwd)
export GEARSIM_LOOPBACK_PRELOAD=${GEARSIM_LOOPBACK_PRELOAD:-$_gs_root/build/src/daemon/gearsim-loopback.so}
unset _gs_root
# `mpirun` typed in this shell preloads the shim. A shell function, not an
# exported LD_PRELOAD, so the build and every other program started from
# this shell are left alone (`command mpirun` runs mpirun without it).
mpirun() {
  if [ -f "$GEARSIM_LOOPBACK_PRELOAD" ]; then
    LD_PRELOAD="$GEARSIM_LOOPBACK_PRELOAD${LD_PRELOAD:+:$LD_PRELOAD}" command mpirun "$@"
  else
    echo "gearsim: no loopback shim at $GEARSIM_LOOPBACK_PRELOAD: mpirun's runtime listens on every interface" >&2
    command mpirun "$@"
  fi
}
# One BLAS thread per rank: ranks are the parallelism, and a fixed thread
# count keeps the floating-point summation order (and so the results)
# independent of how many ranks share the machine.
export OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1
