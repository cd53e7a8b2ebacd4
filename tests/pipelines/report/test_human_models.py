"""The report's "Human models" section, from small artifacts written here by hand (nothing is fitted).

The conclusion names the model the data support (adequacy passing and a leave-one-subject-out
comparison that does not prefer the other one) and gives the cost conclusion from that model with
its adequacy verdict beside it; with no such model it says that no conclusion about the costs is
supported.
"""

import json
import re
from dataclasses import asdict
from html import unescape

import pytest

from scioc.models.design import STUDY, AssistantSpec, Design
from scioc.pipelines.report.human_models import (
    ANGLE_FIT,
    ANGLE_ONLY,
    LOSO_Z,
    conclusion,
    loso_preference,
    read_models,
    section,
    supported,
)
from scioc.pipelines.signed_rank import wilcoxon_signed_rank

MC = [20.0, 22.0, 18.0, 25.0, 21.0, 19.0]
#: SC a factor of 2 below MC in every subject: the exact test's smallest p for 6 pairs, 2/64.
SC_HALF = [v / 2 for v in MC]


def _adequacy(verdict: str) -> dict:
    flagged = {"pass": 0, "fail": 12}.get(verdict, 0)
    if verdict == "not checked":
        return {"verdict": "not checked", "reason": "switched off", "failed_checks": []}
    return {"verdict": verdict, "failed_checks": ["whiteness", "xcorr"] if verdict == "fail" else [],
            "segments_flagged": flagged, "segments": 12}


def _compare(sc) -> dict:
    test = asdict(wilcoxon_signed_rank(MC, sc, alpha=0.05))
    return {"theta1": test, "theta2": test}


def _fit(beta_mean: float, hdi, verdict: str) -> dict:
    beta = {"mean": beta_mean, "sd": 0.05, "median": beta_mean, "hdi": list(hdi), "p_negative": 0.9}
    return {"beta": beta, "ratio": {"median": 0.5, "mean": 0.5, "hdi": [0.4, 0.6]}, "adequacy": _adequacy(verdict)}


def _loso(z: float, reliable: bool = True) -> dict:
    se = 4.0
    by = {f"S0{i}": {"difference": d, "preferred": "delayed" if d > 0 else "maxent"}
          for i, d in enumerate([3.0, 2.5, -0.5, 1.0, 4.0, z * se - 10.0], start=1)}
    n_del = sum(v["preferred"] == "delayed" for v in by.values())
    summary = {"elpd_loo": -500.0, "se": 20.0, "pareto_k": {"n_gt_threshold": 0 if reliable else 2}}
    return {"maxent": summary, "delayed": {**summary, "elpd_loo": -500.0 + z * se}, "by_subject": by,
            "difference": {"elpd_diff": z * se, "se": se, "z": z, "preferred": "delayed" if z > 0 else "maxent",
                           "n_preferring_delayed": n_del, "n": 6, "reliable": reliable}}


def write_run(root, *, maxent=("fail", "fail"), delayed=("pass", "pass"), loso=None, fits=True, convergence=None):
    """A run folder with the artifacts of both human models: (identify verdict, posterior verdict) per model;
    ``convergence``: {model: the sampler-convergence verdict of its fit} (posterior.json)."""
    for name, (ident, tests, fit), (v_id, v_post), sc, beta in (
            ("maxent", ("identify", "compare.json", "fit"), maxent, SC_HALF, -0.69),
            ("delayed", ("identify_delayed", "compare_delayed.json", "fit_delayed"), delayed, MC, 0.01)):
        if v_id is None:
            continue
        (root / ident).mkdir(parents=True)
        (root / ident / "identify.json").write_text(json.dumps({"adequacy": _adequacy(v_id), "human_model": name}))
        (root / tests).write_text(json.dumps(_compare(sc)))
        if fits:
            (root / fit).mkdir()
            hdi = (beta - 0.1, beta + 0.1)
            (root / fit / "contrasts.json").write_text(json.dumps(_fit(beta, hdi, v_post)))
            if convergence and name in convergence:
                (root / fit / "posterior.json").write_text(json.dumps(
                    {"convergence_verdict": {"condition": convergence[name]}}))
    if loso is not None:
        (root / "human_models.json").write_text(json.dumps(loso))
    return root


def _text(markup) -> str:
    return re.sub(r"\s+", " ", unescape(re.sub(r"<[^>]+>", " ", str(markup))))


def test_delayed_passing_and_preferred_by_loso_is_the_supported_model(tmp_path):
    root = write_run(tmp_path, loso=_loso(z=5.0))
    models = read_models(root)
    hm = json.loads((root / "human_models.json").read_text())
    assert supported(models, hm) == ("delayed",)
    text = conclusion(models, hm)
    assert text.startswith("The data support the delayed human model")
    # The cost conclusion is the delayed model's (β near 0, SC = MC: no rejection), with its verdict beside it.
    cost = text[text.index("by it,"):]
    assert "β = +0.010" in cost and "contains 0" in cost and "does not reject" in cost
    assert "β = -0.690" not in text
    assert "passes its adequacy checks (pass at identify, pass at the posterior θ;" in text
    assert "the max-ent model: fail (whiteness, xcorr) at identify, fail (whiteness, xcorr) at the posterior θ" in text
    assert "prefers the delayed model" in text and "z = 5.00" in text


@pytest.mark.parametrize("z", [-3.0, 0.5])
def test_maxent_passing_and_delayed_not_preferred_is_the_supported_model(tmp_path, z):
    root = write_run(tmp_path, maxent=("pass", "pass"), delayed=("fail", "fail"), loso=_loso(z=z))
    models = read_models(root)
    hm = json.loads((root / "human_models.json").read_text())
    assert supported(models, hm) == ("maxent",)
    text = conclusion(models, hm)
    assert text.startswith("The data support the max-ent human model")
    cost = text[text.index("by it,"):]
    assert "β = -0.690" in cost and "excludes 0" in cost and "T = 0, p = 0.031, rejects H0 (no change) at α = 0.05" \
        in cost
    assert ("prefers the max-ent model" if z < 0 else "does not separate the models") in text


@pytest.mark.parametrize("verdicts", [(("fail", "fail"), ("fail", "fail")),
                                      (("fail", "pass"), ("pass", "fail")),  # each fails once
                                      (("not checked", None), ("not checked", None))])
def test_neither_model_passing_supports_no_conclusion_about_costs(tmp_path, verdicts):
    maxent, delayed = verdicts
    root = write_run(tmp_path, maxent=maxent, delayed=delayed, loso=_loso(z=5.0))
    models = read_models(root)
    hm = json.loads((root / "human_models.json").read_text())
    assert supported(models, hm) == ()
    text = conclusion(models, hm)
    assert "no conclusion about the costs" in text
    assert "β =" not in text and "Wilcoxon" not in text  # no cost conclusion without a model that passes


def test_a_passing_model_that_loso_beats_is_not_supported_either(tmp_path):
    root = write_run(tmp_path, maxent=("pass", "pass"), delayed=("fail", "fail"), loso=_loso(z=4.0))
    models = read_models(root)
    hm = json.loads((root / "human_models.json").read_text())
    assert supported(models, hm) == ()
    text = conclusion(models, hm)
    assert text.startswith("The data single out no human model") and "no conclusion about the costs" in text


def test_both_passing_and_loso_undecided_gives_both_conclusions_each_with_its_verdict(tmp_path):
    root = write_run(tmp_path, maxent=("pass", "pass"), delayed=("pass", "pass"), loso=_loso(z=1.0))
    models = read_models(root)
    hm = json.loads((root / "human_models.json").read_text())
    assert supported(models, hm) == ("maxent", "delayed")
    text = conclusion(models, hm)
    assert "by the max-ent model (pass" in text and "by the delayed model (pass" in text
    assert "β = -0.690" in text and "β = +0.010" in text


def test_loso_prefers_only_when_reliable_and_at_least_loso_z_se_apart():
    assert loso_preference(_loso(z=LOSO_Z)) == "delayed"
    assert loso_preference(_loso(z=-LOSO_Z)) == "maxent"
    assert loso_preference(_loso(z=LOSO_Z - 0.01)) is None
    assert loso_preference(_loso(z=10.0, reliable=False)) is None
    assert loso_preference(None) is None


def test_without_fits_the_choice_rests_on_adequacy_and_says_loso_was_not_computed(tmp_path):
    root = write_run(tmp_path, maxent=("fail", None), delayed=("pass", None), fits=False)
    models = read_models(root)
    assert models["delayed"].posterior is None and supported(models, None) == ("delayed",)
    text = conclusion(models, None)
    assert "leave-one-subject-out was not computed" in text and "(no Bayesian fit)" in text and "β" not in text
    html = _text(section(root))
    assert "No human_models.json" in html and "scioc human-models" in html


def test_the_section_shows_the_table_the_loso_numbers_and_the_per_subject_preference(tmp_path):
    root = write_run(tmp_path, loso=_loso(z=5.0))
    html = _text(section(root, STUDY))
    assert "Human models" in html and "max-ent human" in html and "delayed human" in html
    for row in ("adequacy at identify", "adequacy at the posterior θ (fit)", "Wilcoxon on θ1, SC − MC", "β, SC − MC",
                "LOSO ELPD (sum over subjects ± SE)", "subjects better predicted (LOSO)"):
        assert row in html, row
    assert "elpd(delayed) − elpd(max-ent) = +20.0 ± 4.0 (z = 5.00), summed over 6 subjects" in html
    assert "the estimates are reliable" in html
    assert "delayed better: S01 (+3.0), S02 (+2.5), S04 (+1.0), S05 (+4.0), S06 (+10.0)" in html
    assert "max-ent better: S03 (-0.5)" in html
    assert "5 of 6" in html and "1 of 6" in html
    assert "The data support the delayed human model" in html


def test_with_only_maxent_the_section_says_which_and_why(tmp_path):
    write_run(tmp_path, delayed=(None, None))
    for measured in (False, True):
        html = _text(section(tmp_path, STUDY))
        assert "Only the max-ent human model" in html
        assert "not requested" in html and "--human-model maxent,delayed" in html


def test_without_a_delayed_fit_the_section_says_so_and_concludes_from_a_passing_model(tmp_path):
    import shutil

    write_run(tmp_path, delayed=("pass", None))
    shutil.rmtree(tmp_path / "fit_delayed")
    html = _text(section(tmp_path, STUDY))
    assert "The delayed human model has no Bayesian fit here." in html
    assert "no fit" in html and "(no Bayesian fit)" in html
    # the conclusion still comes from a model that passes, with its verdict beside it
    assert "The data support the delayed human model: it passes its adequacy checks (pass at identify, no fit;" in html
    assert "leave-one-subject-out was not computed" in html


def test_a_comparison_of_the_angle_fits_says_what_it_scores(tmp_path):
    write_run(tmp_path, loso=_loso(z=5.0))
    hm = json.loads((tmp_path / "human_models.json").read_text())
    html = _text(section(tmp_path, STUDY)).replace("“", "\"").replace("”", "\"")
    assert "scores the encoder's angles" not in html
    hm["fits"] = {"maxent": ANGLE_FIT, "delayed": "fit_delayed"}
    (tmp_path / "human_models.json").write_text(json.dumps(hm))
    html = _text(section(tmp_path, STUDY)).replace("“", "\"").replace("”", "\"")
    assert "The leave-one-subject-out comparison scores the encoder's angles: " + ANGLE_ONLY in html


def test_several_levels_get_a_row_per_contrast_with_holm(tmp_path):
    design = Design(levels=("none", "weak", "auto"), baseline="none",
                    assistants=(("weak", AssistantSpec(kind="linear", gain=(2.0, 0.1), reference_gain=2.0)),
                                ("auto", AssistantSpec(kind="mpc"))), effects=(-0.35, -0.7))
    write_run(tmp_path, loso=_loso(z=5.0))
    test = {**asdict(wilcoxon_signed_rank(MC, MC, alpha=0.05)), "p_holm": 1.0, "reject_holm": False}
    cmp = {"baseline": "none", "contrasts": {v: {"theta1": test, "theta2": test} for v in ("weak", "auto")}}
    fit = {"baseline": "none", "levels": ["none", "weak", "auto"], "adequacy": _adequacy("pass"),
           "contrasts": {v: _fit(0.01, (-0.09, 0.11), "pass") for v in ("weak", "auto")}}
    (tmp_path / "compare_delayed.json").write_text(json.dumps(cmp))
    (tmp_path / "fit_delayed" / "contrasts.json").write_text(json.dumps(fit))
    html = _text(section(tmp_path, design))
    assert "Wilcoxon on θ1, weak − none" in html and "β, auto − none" in html
    assert "Holm p = 1, does not reject H0 (no change) at α = 0.05" in html
    assert "weak − none: Wilcoxon on θ1" in html and "auto − none: Wilcoxon on θ1" in html
    assert not re.search(r"(?<!\w)(MC|SC)(?!\w)", html)


def test_a_beta_from_a_sampler_that_did_not_converge_says_so_wherever_it_appears(tmp_path):
    # Sampler convergence is not model adequacy: a supported model's β from an unconverged fit is flagged.
    failed = "fail: no_divergences, rhat_le_1.01"
    root = write_run(tmp_path, loso=_loso(z=5.0), convergence={"maxent": "pass", "delayed": failed})
    models = read_models(root)
    assert models["delayed"].convergence == failed and models["maxent"].convergence == "pass"
    text = conclusion(models, json.loads((root / "human_models.json").read_text()))
    assert text.startswith("The data support the delayed human model")
    assert f"β = +0.010, 94 % HDI [-0.090, +0.110] (contains 0); but the sampler did not converge ({failed}), " \
           "so this β is not a result to rely on" in text
    html = _text(section(root, STUDY))
    assert "sampler convergence (fit)" in html and failed in html
    assert html.count("not a result to rely on") == 2  # the table's β and the conclusion's; max-ent's β unflagged
    assert "what to try" not in html  # no diagnostics recorded, no advice
    # With the fit's diagnostics the table says what to try, from its own numbers (pipelines.fit.diagnostics.remedies)
    side = json.loads((root / "fit_delayed" / "posterior.json").read_text())
    side.update(sampler={"chains": 4, "draws": 1000, "target_accept": 0.9}, diagnostics={"condition": {
        "sampler": {"divergences": 2}, "passed": False,
        "population": {"sigma_m_scale": {"rhat": 1.03, "ess_bulk": 128.0, "ess_tail": 192.0}}}})
    (root / "fit_delayed" / "posterior.json").write_text(json.dumps(side))
    assert len(read_models(root)["delayed"].remedies) == 3
    html = _text(section(root, STUDY))
    assert "what to try (fit's sampler)" in html and "refit with --target-accept 0.95" in html
    assert "about --draws 3200 per chain" in html and "R-hat of sigma_m_scale 1.030" in html


def test_too_few_importance_points_make_the_loso_unreliable_and_the_section_says_why(tmp_path):
    loso = _loso(z=5.0, reliable=False)
    loso["difference"].update(unreliable_because=["importance-sampling ESS below 100"],
                              importance={"is_ess_loo_min": 12.0, "threshold": 100, "mcse": 0.61})
    assert loso_preference(loso) is None
    root = write_run(tmp_path, loso=loso)
    html = _text(section(root, STUDY))
    assert "the estimates are unreliable (importance-sampling ESS below 100)" in html
    assert "smallest ESS is 12, the Monte Carlo SE of the difference 0.61" in html
    assert "leave-one-subject-out is unreliable (importance-sampling ESS below 100;" in html


def test_the_table_names_the_population_of_R_each_fit_used_and_why(tmp_path):
    """A delayed fit's posterior.json names its population of the subjects' R (and ρ's form under the policy scale)
    and why; the table shows it beside the max-ent fit's, the paper's lognormal one. Without that record (older
    fits) the row is left out."""
    root = write_run(tmp_path, loso=_loso(z=5.0), convergence={"maxent": "pass", "delayed": "pass"})
    assert "population of the subjects" not in _text(section(root))
    side = json.loads((root / "fit_delayed" / "posterior.json").read_text())
    reason = "policy_scale: the estimates leave the R of 5 of 6 subjects loose"
    side.update({"delayed_priors": {"R_population": "policy_scale"}, "R_population_reason": reason,
                 "delayed_form": {"rho": "folded_centred"}})
    (root / "fit_delayed" / "posterior.json").write_text(json.dumps(side))
    text = _text(section(root))
    assert ("population of the subjects' R (fit) lognormal (the paper's model's) policy_scale, ρ = R^(-1/2) "
            f"folded_centred (chosen by the estimates: {reason})") in text
    side.update({"delayed_priors": {"R_population": "lognormal"}, "R_population_reason": "given"})
    (root / "fit_delayed" / "posterior.json").write_text(json.dumps(side))
    assert "lognormal (the paper's model's) lognormal (given)" in _text(section(root))
