"""``scioc compare``: the paper's hypothesis test (Section IV-G, V-A) on identified parameters.

The exact Wilcoxon matched-pairs signed-rank test (:mod:`scioc.pipelines.signed_rank`) of
θ1 = q11/R and θ2 = q22/R, each level against the baseline (Holm across levels), with the
rank-biserial effect size r = (W+ − W−) / (W+ + W−). Zero differences are dropped; ties get
average ranks, and the exact null is then approximate (scipy's p-value errs conservative).
:func:`check_estimates` lists every unit left out of the test with its reason.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pandas as pd

from scioc.models.adequacy import STATISTICS, study_verdict
from scioc.models.design import CONDITIONS, STUDY
from scioc.models.identify import PLAUSIBLE_THETA1
from scioc.pipelines import lineage
from scioc.pipelines.adequacy import format_adequacy, not_checked
from scioc.pipelines.experiment import parse_experiment, sidecar
from scioc.pipelines.human_model.registry import get
from scioc.pipelines.io import StudyFileError, read_table
from scioc.pipelines.prepare import IdentifySettings
from scioc.pipelines.signed_rank import ALPHA, holm, wilcoxon_signed_rank
from scioc.pipelines.storage import WRITTEN_BY, check_output_file, write_text_atomic

#: The command whose results :func:`compare_to_file` writes (:data:`scioc.pipelines.storage.WRITTEN_BY`).
COMMAND = "scioc compare"


def _converged(values: pd.Series) -> np.ndarray:
    """``converged`` as booleans, whether stored as bool (Parquet) or text (CSV)."""
    if values.dtype == bool:
        return values.to_numpy()
    return values.astype(str).str.strip().str.lower().isin(("true", "1", "1.0")).to_numpy()


def _shown(value) -> str:
    try:
        return f"{float(value):g}"
    except (TypeError, ValueError):
        return repr(value)


def check_estimates(estimates: pd.DataFrame, path="<table>", *, include_nonconverged: bool = False,
                    levels=CONDITIONS):
    """Validate an estimates table and choose the units the matched-pairs test may use.

    Parameters
    ----------
    estimates : DataFrame
        One row per subject × condition with ``theta1``, ``theta2`` and optionally
        ``converged``, ``implausible`` and ``message``, as ``scioc identify`` writes.
    path : str
        Named in error messages.
    include_nonconverged : bool
        Keep units that did not converge or ended at the edge of the search.
    levels : sequence of str
        Baseline first. A unit needs its subject's baseline unit; a baseline unit, one other.

    Returns
    -------
    usable : DataFrame
    excluded : list of dict
        ``{"subject", "condition", "reason"}`` per unit left out, in table order.

    Raises
    ------
    StudyFileError
        A missing column, an unknown label, or a duplicated subject × condition.
    """
    for col in ("subject", "condition", "theta1", "theta2"):
        if col not in estimates.columns:
            raise StudyFileError(path, "required column is missing", column=col)
    df = estimates.reset_index(drop=True).copy()
    df["subject"] = df["subject"].astype(str).str.strip()
    df["condition"] = df["condition"].astype(str).str.strip()
    levels = tuple(levels)
    bad = ~df["condition"].isin(levels).to_numpy()
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise StudyFileError(path, f"unknown condition label '{df['condition'][i]}' (expected "
                             f"{' or '.join(levels) if len(levels) == 2 else 'one of ' + ', '.join(levels)})",
                             column="condition", row=i)
    dup = df.duplicated(["subject", "condition"], keep=False).to_numpy()
    if dup.any():
        i = int(np.flatnonzero(dup)[0])
        key = (df["subject"][i], df["condition"][i])
        rows = np.flatnonzero(dup & (df["subject"] == key[0]).to_numpy() & (df["condition"] == key[1]).to_numpy())
        raise StudyFileError(path, f"subject {key[0]}, condition {key[1]} appears in rows "
                             f"{', '.join(map(str, rows))}; each subject × condition needs exactly one estimate")
    theta1 = pd.to_numeric(df["theta1"], errors="coerce").to_numpy(dtype=float)
    theta2 = pd.to_numeric(df["theta2"], errors="coerce").to_numpy(dtype=float)
    converged = _converged(df["converged"]) if "converged" in df.columns else np.ones(len(df), bool)
    implausible = _converged(df["implausible"]) if "implausible" in df.columns else np.zeros(len(df), bool)
    reasons = {}
    for i in range(len(df)):
        if not (np.isfinite(theta1[i]) and theta1[i] > 0):
            reasons[i] = f"theta1 = {_shown(df['theta1'][i])} is not a finite positive number"
        elif not (np.isfinite(theta2[i]) and theta2[i] >= 0):
            reasons[i] = f"theta2 = {_shown(df['theta2'][i])} is not a finite number >= 0"
        elif not converged[i] and not include_nonconverged:
            msg = str(df["message"][i]) if "message" in df.columns else ""
            reasons[i] = "identification did not converge" + (f" ({msg})" if msg else "")
        elif implausible[i] and not include_nonconverged:
            reasons[i] = (f"theta1 = {_shown(df['theta1'][i])} is at the edge of the search "
                          f"(outside {PLAUSIBLE_THETA1[0]:g}..{PLAUSIBLE_THETA1[1]:g} 1/rad²)")
    ok = np.array([i not in reasons for i in range(len(df))])
    usable_keys = set(zip(df["subject"][ok], df["condition"][ok]))
    all_keys = set(zip(df["subject"], df["condition"]))
    base = levels[0]
    for i in np.flatnonzero(ok):
        subject, condition = df["subject"][i], df["condition"][i]
        others = [base] if condition != base else list(levels[1:])
        named = others[0] if len(others) == 1 else "other-level"
        if not any((subject, o) in all_keys for o in others):
            reasons[int(i)] = f"no {named} estimate for this subject"
        elif not any((subject, o) in usable_keys for o in others):
            reasons[int(i)] = f"its {named} estimate{'s are' if len(others) > 1 else ' is'} left out"
    excluded = [{"subject": df["subject"][i], "condition": df["condition"][i], "reason": reasons[i]}
                for i in sorted(reasons)]
    keep = np.array([i not in reasons for i in range(len(df))], dtype=bool)
    usable = df[keep].assign(theta1=theta1[keep], theta2=theta2[keep])
    return usable, excluded


def paired(estimates: pd.DataFrame, column: str, pair=CONDITIONS) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Values of ``column`` in the two levels of ``pair`` (default MC, SC) for subjects that have both."""
    wide = estimates.pivot_table(index="subject", columns="condition", values=column, aggfunc="first")
    for c in pair:
        if c not in wide.columns:
            raise ValueError(f"no {c} estimates: the matched-pairs test needs both conditions")
    wide = wide.dropna(subset=list(pair))
    return wide[pair[0]].to_numpy(), wide[pair[1]].to_numpy(), list(wide.index)


def _tests(usable: pd.DataFrame, pair, alpha: float) -> dict:
    out = {}
    for col in ("theta1", "theta2"):
        testable = set(pair) <= set(usable["condition"])  # else no pair: every unit of a level left out
        a, b, _ = paired(usable, col, pair) if testable else (np.array([]), np.array([]), [])
        out[col] = {k: _finite_or_none(v) for k, v in asdict(wilcoxon_signed_rank(a, b, parameter=col,
                                                                                 alpha=alpha)).items()}
        if not out[col]["n_pairs"]:  # no pair: no p-value, rather than the p = 1 of no evidence
            out[col]["p_value"] = None
    return out


def _nothing_to_test(tests: dict, pair) -> str | None:
    """Why a contrast has no test (no subject with usable estimates of both levels), or None."""
    if tests["theta1"]["n_pairs"]:
        return None
    return (f"no subject has usable estimates of both {pair[0]} and {pair[1]} (the units left out are listed with "
            "their reasons)")


def compare_estimates(estimates: pd.DataFrame, *, alpha: float = ALPHA, include_nonconverged: bool = False,
                      path="<table>", levels=CONDITIONS) -> dict:
    """Signed-rank tests of θ1 and θ2 of each level against the baseline on the units :func:`check_estimates` keeps.

    With two levels (baseline first) the ``theta1`` and ``theta2`` tests are at the top; with more,
    ``contrasts`` holds them per level with Holm-adjusted ``p_holm``/``reject_holm`` (family-wise
    error at most α). Also ``excluded``, ``unpaired_subjects``, ``include_nonconverged`` and ``adequacy``.
    """
    levels = tuple(levels)
    usable, excluded = check_estimates(estimates, path, include_nonconverged=include_nonconverged, levels=levels)
    for c in levels:
        if not (estimates["condition"].astype(str).str.strip() == c).any():
            raise ValueError(f"no {c} estimates: the matched-pairs test needs every condition")
    if len(levels) == 2:
        out = _tests(usable, levels, alpha)
        empty = {levels[1]: _nothing_to_test(out, levels)}
    else:
        per = {c: _tests(usable, (levels[0], c), alpha) for c in levels[1:]}
        empty = {c: _nothing_to_test(per[c], (levels[0], c)) for c in levels[1:]}
        tested = [c for c in levels[1:] if not empty[c]]  # Holm's family: the contrasts with a test
        for col in ("theta1", "theta2"):
            adj = dict(zip(tested, holm([per[c][col]["p_value"] for c in tested])))
            for c in levels[1:]:
                a = adj.get(c)
                per[c][col].update(p_holm=None if a is None else float(a), reject_holm=bool(a is not None
                                                                                             and a <= alpha))
        out = {"baseline": levels[0], "contrasts": per,
               "multiplicity": f"Holm across the {len(tested)} levels against {levels[0]}, per parameter, at "
                               f"family-wise α = {alpha:g}" + "".join(f"; not {c}: nothing to test" for c in levels[1:]
                                                                       if empty[c])}
    out["nothing_to_test"] = {c: why for c, why in empty.items() if why}
    counts = estimates.assign(subject=estimates["subject"].astype(str).str.strip()).groupby("subject").size()
    out["unpaired_subjects"] = sorted(counts.index[counts < 2])
    out["excluded"] = excluded
    out["include_nonconverged"] = bool(include_nonconverged)
    out["adequacy"] = adequacy_of_estimates(estimates, path)
    return out


def adequacy_of_estimates(estimates: pd.DataFrame, path="<table>") -> dict:
    """The adequacy verdict of an estimates table's ``adequacy_p_*`` columns, as ``scioc identify`` combines them.

    The test's result is never shown without the verdict on the model behind it. Raises
    StudyFileError for a p-value outside (0, 1], naming the file, column and first bad row.
    """
    cols = {k: f"adequacy_p_{k}" for k in STATISTICS}
    if not set(cols.values()) <= set(estimates.columns) or "adequacy_p" not in estimates.columns:
        return not_checked("the estimates carry no adequacy columns (identified with --adequacy-boot 0, or "
                           "not by scioc identify)")
    values = {}
    for col in ["adequacy_p", *cols.values()]:
        v = pd.to_numeric(estimates[col], errors="coerce").to_numpy(dtype=float)
        bad = ~((v > 0) & (v <= 1))
        if bad.any():
            raise StudyFileError(path, "an adequacy p-value must lie in (0, 1]", column=col,
                                 row=int(np.flatnonzero(bad)[0]))
        values[col] = v
    out = study_verdict({k: values[c] for k, c in cols.items()}, values["adequacy_p"])
    model = human_model_of(estimates)
    out["human_model"] = model
    out["checks"] = get(model).adequacy_check_text
    return out


def human_model_of(estimates: pd.DataFrame) -> str:
    """The human model the estimates were identified with (its ``human_model`` column; ``maxent`` without one)."""
    if "human_model" not in estimates.columns:
        return IdentifySettings.human_model  # estimates written before the column: the default model
    models = sorted(set(estimates["human_model"].astype(str)))
    if len(models) != 1:
        raise ValueError(f"the estimates mix human models ({', '.join(models)}); compare one model's estimates")
    return models[0]


def _finite_or_none(value):
    """JSON has no NaN: an undefined statistic (no non-zero differences) is stored as null."""
    return None if isinstance(value, float) and not math.isfinite(value) else value


def estimates_design(estimates_path):
    """The experiment recorded in ``identify.json`` beside ``estimates_path``, and its file; else ``(STUDY, None)``."""
    meta = Path(estimates_path).parent / "identify.json"
    if not meta.is_file():
        return STUDY, None
    side = json.loads(meta.read_text())
    if "experiment" not in side:
        return STUDY, None
    return parse_experiment(side["experiment"], f"{meta} (experiment)"), side.get("experiment_file")


def compare_to_file(estimates_path, out_path, *, alpha: float = ALPHA, include_nonconverged: bool = False) -> dict:
    """Read ``estimates.parquet``, test with the levels of :func:`estimates_design`, write ``compare.json`` atomically.

    The estimates must be those their ``identify.json`` records (LineageError naming both otherwise); ``out_path``
    never replaces an input (:func:`scioc.pipelines.storage.check_output_file`, ValueError).
    """
    meta = Path(estimates_path).parent / "identify.json"
    check_output_file(out_path, COMMAND, {"the estimates file": estimates_path, "the identification's sidecar": meta})
    if not Path(estimates_path).is_file():
        raise StudyFileError(estimates_path, "no such file")
    found = lineage.identification(estimates_path)
    design, source = estimates_design(estimates_path)
    df = read_table(estimates_path)
    res = compare_estimates(df, alpha=alpha, include_nonconverged=include_nonconverged, path=estimates_path,
                            levels=design.ordered_levels)
    res.update(sidecar(design, source))
    res["inputs"] = {"estimates": lineage.entry(estimates_path),
                     "identification": None if found is None else lineage.entry(found[0])}
    write_text_atomic(Path(out_path), json.dumps({**res, WRITTEN_BY: COMMAND}, indent=2, allow_nan=False) + "\n")
    return res


def format_compare(res: dict) -> str:
    """The tests as text, after the model-adequacy verdict (and a caveat when it fails)."""
    adequacy = res.get("adequacy") or not_checked("not recorded")
    lines = [f"human model: {adequacy.get('human_model', 'maxent')}", format_adequacy(adequacy)]
    if adequacy["verdict"] != "pass":
        lines.append("CAVEAT: the test below compares costs of a human model that "
                     + ("fails its adequacy checks; a 'significant' change may be an artifact of model misfit"
                        if adequacy["verdict"] == "fail" else "was not checked for adequacy"))
    tests = ({"": res} if "contrasts" not in res else
             {f"{c} − {res['baseline']}": r for c, r in res["contrasts"].items()})
    for name, t in tests.items():
        lines.append(f"Wilcoxon matched-pairs signed-rank test, {name or 'SC − MC'} (exact two-sided)")
        holm_col = "p_holm" in t["theta1"]
        lines.append(f"{'':>10} {'N':>4} {'W+':>8} {'W−':>8} {'T':>8} {'p':>10} {'crit':>6} {'reject':>7} {'r_rb':>7}"
                     + (f" {'p_holm':>8}" if holm_col else ""))
        for col in ("theta1", "theta2"):
            r = t[col]
            crit = "-" if r["critical_value"] is None else str(r["critical_value"])
            r_rb = "-" if r["rank_biserial"] is None else f"{r['rank_biserial']:.3f}"
            p, p_holm = (("-" if v is None else f"{v:.3g}") for v in (r["p_value"], r.get("p_holm")))
            lines.append(
                f"{col:>10} {r['n']:>4} {r['w_plus']:>8.1f} {r['w_minus']:>8.1f} {r['T']:>8.1f} {p:>10} "
                f"{crit:>6} {str(r['reject']):>7} {r_rb:>7}" + (f" {p_holm:>8}" if holm_col else ""))
    first = next(iter(tests.values()))
    lines.append(f"α = {first['theta1']['alpha']:g}; reject H0 when T <= crit"
                 + (f"; {res['multiplicity']}" if "multiplicity" in res else ""))
    for level, why in (res.get("nothing_to_test") or {}).items():
        lines.append(f"NOTHING TO TEST against {level}: {why}")
    excluded = res.get("excluded", [])
    if excluded:
        lines.append(f"left out of the test ({len(excluded)} units):")
        lines.extend(f"  {e['subject']} {e['condition']}: {e['reason']}" for e in excluded)
    if res.get("include_nonconverged"):
        lines.append("units whose identification did not converge are included (--include-nonconverged)")
    return "\n".join(lines)
