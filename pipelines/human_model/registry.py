"""The interface every human model implements, and the registry that finds one by name.

A stage asks the registry for the model a study is analysed with (:func:`get`) and calls its methods;
it never compares the model's name. :mod:`scioc.pipelines.human_model` registers the built-in
models (``maxent``, ``delayed``); another is added with :func:`register`.
"""

from __future__ import annotations

from typing import NamedTuple


class FitOutcome(NamedTuple):
    """What a human model's hierarchical fit hands back to ``scioc fit``'s stage."""

    fits: dict  # name -> InferenceData/DataTree; "condition" is the model with condition effects
    diagnostics: dict  # name -> sampler diagnostics and verdict
    results: dict  # contrasts.json: contrasts, LOO, checks, adequacy
    timing: dict
    sidecar: dict  # the model's own sidecar fields (sampler options, forms and their reasons)
    ppc: object  # the posterior predictive bands (DataFrame)
    ppc_draws: object  # the posterior predictive draws (Dataset)


class HumanModel:
    """A model of the human whose recordings are analysed.

    Subclasses set :attr:`name`, :attr:`description` and :attr:`adequacy_check_text`, and implement the
    methods; each method's docstring says which stage calls it. Instances hold no state.
    """

    #: The name users give (``--human-model NAME``), the key in sidecars and tables.
    name: str = ""
    #: One line for the CLI and reports.
    description: str = ""
    #: What the adequacy checks of this model test, for compare.json and the report.
    adequacy_check_text: str = ""
    #: The likelihoods ``scioc loglik --likelihood`` can evaluate under this model.
    likelihoods: tuple = ("torques",)
    #: Whether identifying one unit takes long enough to show a progress bar.
    slow_identification: bool = False
    #: The keys ``--sampler-config`` may set for this model's fit, with their allowed values (None: any).
    sampler_keys: dict = {}

    #: Simulation-based calibration (scioc calibrate): the levels, the negative controls (a wrong fit of the same
    #: data), the default one per level, the suffix of the run folders, and what the replications can record and fit.
    calibration_levels: tuple = ()
    negative_controls: tuple = ()
    default_negative_control: dict = {}
    calibration_suffix: str = ""
    calibration_likelihoods: dict = {"unit": ("torques",), "study": ("torques",)}

    # identification (scioc identify)
    def identify_unit(self, prepared, idx, plant, settings):
        """The ML estimate of one unit: the prepared segments ``idx``, sharing θ."""
        raise NotImplementedError

    def estimate_columns(self, estimate, prepared, idx) -> dict:
        """Columns of ``estimates.parquet`` beyond θ and its errors."""
        return {}

    def adequacy_parameters(self, prepared, fitted, plant, settings) -> dict | None:
        """Per segment, the fitted parameters the adequacy bootstrap draws with beyond θ (None: θ alone)."""
        return None

    def cross_prediction_parameters(self, row):
        """A unit's fitted parameters for its mean behaviour (:meth:`mean_behaviour`), from its estimates row."""
        raise NotImplementedError

    def mean_behaviour(self, p, parameters, plant, settings):
        """The human's mean behaviour on prepared segment ``p`` (``.x`` (K+1, 2), ``.u_H`` (K,))."""
        raise NotImplementedError

    def identify_sidecar(self, estimates, settings) -> dict:
        """Fields of ``identify.json`` this model adds."""
        return {}

    def implausible_fields(self, row) -> dict:
        """Fields of an implausible unit's record in ``identify.json`` beyond θ1."""
        return {}

    def identify_notes(self, meta: dict) -> list[str]:
        """Lines ``scioc identify`` prints about this model's identification."""
        return []

    # likelihood (scioc loglik)
    def loglik(self, theta, prepared, plant, design, parameters, likelihood: str):
        """Log-likelihood per prepared segment under ``theta`` and the model's ``parameters``."""
        raise NotImplementedError

    def loglik_parameters(self, dt: float, delay_s, tau_nm, sigma_m):
        """The model's parameters beyond θ for ``scioc loglik``, validated (ValueError otherwise)."""
        raise NotImplementedError

    # hierarchical fit (scioc fit)
    def check_fit_data(self, prepared) -> None:
        """Raise InputDataError where this model's fit cannot use the study's recordings."""

    def fit_likelihood(self, prepared, requested: str | None) -> str:
        """What the fit scores (``--likelihood``): ``requested``, checked against :attr:`likelihoods`, or the model's
        default for these recordings (the torques)."""
        if requested is None:
            return "torques"
        if requested not in self.likelihoods:
            raise ValueError(f"--likelihood {requested} is not one of the {self.name} human model's: "
                             f"{', '.join(self.likelihoods)}")
        return requested

    def sampler_options(self, options: dict, source: str) -> dict:
        """``options`` (from ``--sampler-config``) validated against :attr:`sampler_keys`, naming ``source``."""
        bad = sorted(set(options) - set(self.sampler_keys))
        if bad:
            known = ", ".join(sorted(self.sampler_keys)) or "none"
            raise ValueError(f"{source}: unknown key(s) {', '.join(bad)} for the {self.name} human model's fit "
                             f"(known: {known})")
        for key, value in options.items():
            allowed = self.sampler_keys[key]
            if allowed is not None and value not in allowed:
                raise ValueError(f"{source}: {key} must be one of {', '.join(map(str, allowed))}; got {value!r}")
        return dict(options)

    def default_tune(self, options: dict) -> int:
        """Warm-up draws per chain when ``--tune`` is not given."""
        raise NotImplementedError

    def plan(self, ctx) -> dict:
        """The fit's choices (parameterization, populations, warm-up, rate) and their reasons, before sampling."""
        raise NotImplementedError

    def fit(self, ctx) -> FitOutcome:
        """Sample the hierarchical model(s) of the prepared study in ``ctx`` (:class:`FitContext`) and check them."""
        raise NotImplementedError

    def sampler_record(self, ctx, outcome: FitOutcome) -> dict:
        """Which sampler the fit used and its mass matrix, for the sidecar."""
        raise NotImplementedError

    def fit_summary_lines(self, side: dict) -> list[str]:
        """Lines ``scioc fit`` prints about this model's fit beside β."""
        return []

    def subject_loo_terms(self, side: dict, folder, prepared, batch, plant):
        """For leave-one-subject-out of a finished fit: None where the max-ent terms are the model's, else a
        function of a subject's flat draws that gives its terms (:func:`scioc.pipelines.fit.loo.subject_elpd`)."""
        return None

    def posterior_adequacy(self, idata, prepared, plant, side: dict, folder, at: str) -> dict:
        """The adequacy check at a posterior point of a finished fit (``scioc adequacy``)."""
        raise NotImplementedError

    # calibration (scioc calibrate)
    def calibration_replication(self, level: str):
        """The function that runs one replication at ``level``: ``(config, i, seed_sequence) -> dict``."""
        raise NotImplementedError

    def calibration_fingerprint(self, d: dict) -> dict:
        """A calibration configuration's fingerprint fields (``d``, from its dataclass), as this model keys them."""
        return d

    # recovery (scioc recovery)
    def recovery(self, estimates, truth) -> dict:
        """This model's parameters beyond θ against a simulation's truth."""
        return {}


class FitContext(NamedTuple):
    """Everything a human model's fit reads: the prepared study, the sampler's settings, the inputs it combines."""

    prepared: object  # PreparedStudy
    batch: object  # SegmentBatch of the prepared segments
    plant: object
    priors: object  # scioc.models.bayes.hierarchical.Priors
    form: object  # Parameterization of the log θ1 blocks
    form_reason: str
    estimates: object  # DataFrame of scioc identify, or None
    estimates_path: object
    truth_dir: object
    subject: str  # the subject of the posterior predictive bands
    seeds: dict
    chains: int
    draws: int
    tune: int
    tune_given: bool  # --tune given, not the model's default
    cores: int | None
    show_progress: bool
    target_accept: float | None
    adequacy_at: str
    options: dict  # the model's validated sampler options
    likelihood: str = "torques"  # what the fit scores: the recorded (or reconstructed) torques, or the angles


def parameterization_text(form) -> str:
    """A block-form dataclass (e.g. :class:`scioc.models.bayes.blocks.Parameterization`) as ``name form, ...``."""
    from dataclasses import asdict

    return ", ".join(f"{k} {v}" for k, v in asdict(form).items())


#: The models ``scioc run`` analyses: the paper's always, the alternative too when the paper's fails its adequacy
#: checks (docs/decisions/run-human-models.md); leave-one-subject-out compares them in this order.
PRIMARY, ALTERNATIVE = "maxent", "delayed"

_MODELS: dict[str, HumanModel] = {}


def register(model: HumanModel) -> HumanModel:
    """Add ``model`` under its name (replacing one of the same name); returns it."""
    if not model.name:
        raise ValueError("a human model needs a name")
    _MODELS[model.name] = model
    return model


def unregister(name: str) -> None:
    """Remove the model registered under ``name`` (tests add and remove models)."""
    _MODELS.pop(name, None)


def names() -> tuple[str, ...]:
    """The registered models' names, in registration order."""
    return tuple(_MODELS)


def get(name: str) -> HumanModel:
    """The model registered under ``name``; ValueError naming the known ones otherwise."""
    try:
        return _MODELS[name]
    except (KeyError, TypeError):
        raise ValueError(f"human model must be one of {', '.join(_MODELS)}; got {name!r}") from None
