"""Everything that needs PyMC or PyTensor: the likelihood Ops, the hierarchical and unit models,
leave-one-subject-out.

Kept apart so that the numba core of :mod:`scioc.models` imports without them. Import its modules.
"""
