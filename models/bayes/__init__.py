"""The PyMC side: everything that needs PyMC or PyTensor, kept apart so that the numba core imports without them.

Likelihood Ops: ``op`` (max-ent), ``delayed_op``, ``delayed_lag``, ``delayed_value``. Models: ``hierarchical`` and
``blocks`` (max-ent); ``delayed_model``, ``delayed_blocks``, ``delay_step`` (delayed); ``unit_model``,
``unit_delayed`` (one unit, for SBC). Sampling coordinates: ``whiten``, ``whiten_draws``, ``pivot_tails``. Checks:
``prior_predictive``, ``subject_loo``, ``delayed_loo``, ``delayed_windows``. Import the modules themselves.
"""
