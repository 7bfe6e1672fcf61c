"""airl: adversarial inverse reinforcement learning with changing dynamics (a command-line experiment runner)."""

import os

__version__ = "0.1.0"

# The planner's numba kernels run on OpenMP threads (numba's "omp" layer). GNU OpenMP's default
# lets an idle thread spin for a while between parallel regions; the planner enters about sixty
# short regions a call, and on a machine whose cores are busy with other work the spinning threads
# crowd out the working ones: the 32x32 Objectworld fit took 20.3 s instead of 6.6 s under a load
# of about 3 on 2 cores (the duplicate-removal kernel 13.8 ms a step instead of 0.4 ms). Passive
# waiting costs a wake-up per region (microseconds). Set before numba loads OpenMP; a value the
# user chose is kept.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
