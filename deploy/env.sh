# SPDX-License-Identifier: MIT
# Environment for running gearsimd under Open MPI on one machine (sourced).
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1
export OMPI_MCA_btl_vader_single_copy_mechanism=none
export HDF5_USE_FILE_LOCKING=FALSE
# One BLAS thread per rank: ranks are the parallelism, and a fixed thread
# count keeps the floating-point summation order (and so the results)
# independent of how many ranks share the machine.
export OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1
