"""Everything that needs PyMC or PyTensor: the likelihood Op, the hierarchical and unit models, leave-one-subject-out.

Kept apart so that the numba core of :mod:`models` (plant, lq, maxent, segment, simulate,
humans, reconstruct, adequacy) imports without them. This package imports nothing
itself: import its modules.
"""
