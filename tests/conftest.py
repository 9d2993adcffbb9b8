"""Suite-wide settings.

One BLAS thread per process. The suite flies the mock in real time (up to 5x) beside numerical
benches (the optimal bound's L-BFGS-B calls BLAS on tiny matrices every iteration): on a 2-core
machine, BLAS worker threads left spinning by one test compete with a later test's flight loop
for the cores. Set before numpy is first imported (this file is imported before any test
module); an explicit ``OPENBLAS_NUM_THREADS`` in the environment wins.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
