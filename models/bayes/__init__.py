"""Everything that needs PyMC or PyTensor: the likelihood Op, the hierarchical and unit models, leave-one-subject-out.

Kept apart so that the numba core of :mod:`models` (plant, lq, maxent, segment, simulate,
humans, reconstruct, adequacy) imports without them. Import its modules.

One setting, here, before any of its Ops is compiled: PyTensor's numba backend compiles
graphs without fast-math (``numba__fastmath``; PyTensor's default turns on reassociation,
contraction and approximate functions). With it, a graph function compiled in a process that
had just compiled the likelihood kernels (an empty numba cache: the first run on a new
machine, or after any edit of :mod:`models`) computed other last bits than the same function
in a process that loaded them from the cache, and HMC turns such bits into other chains:
"same seed, same draws" held only once the cache was warm. Without it the bits agree
(``tests/models/test_numba_cache.py``). The kernels dominate the cost of every graph here.
"""

import pytensor

pytensor.config.numba__fastmath = False
