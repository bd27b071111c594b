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
# the daemon's launchers preload build/src/daemon/gearsim-loopback.so into
# mpirun for that (GEARSIM_LOOPBACK_PRELOAD below; not exported as
# LD_PRELOAD here, so that the build and other programs of this shell are
# left alone).
export OMPI_MCA_btl=self,vader
export OMPI_MCA_oob_tcp_if_include=lo OMPI_MCA_btl_tcp_if_include=lo
_gs_root=$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")/.." 2>/dev/null && pwd)
export GEARSIM_LOOPBACK_PRELOAD=${GEARSIM_LOOPBACK_PRELOAD:-$_gs_root/build/src/daemon/gearsim-loopback.so}
unset _gs_root
# One BLAS thread per rank: ranks are the parallelism, and a fixed thread
# count keeps the floating-point summation order (and so the results)
# independent of how many ranks share the machine.
export OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1
