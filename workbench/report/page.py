"""The identification report: one self-contained HTML page, read like a test-lab report.

`render_report` turns a `workbench.workflow.runs.Run` (campaign studies and section 5 predictions)
into ``index.html``: figures embedded as base64 PNG (`workbench.report.plots`), CSS inline, no script and
no external address, so that the page opens offline and prints. Plots come before tables. Synthetic
campaigns carry a banner ("SYNTHETIC - virtual test rig") and are never called measured.

The figures of the benchmarks live in `workbench.report.plots`; ``plt``, ``save_figure``,
``moment_error_figure`` and ``plot_moment_errors`` are re-exported here for the scripts that
imported them from this module before the split.
"""

from __future__ import annotations

import platform
from collections.abc import Iterable, Sequence

import numpy as np

from workbench import __version__
from workbench.identify.bayes import load_arviz
from workbench.identify.record import ESS_LIMIT, RHAT_LIMIT
from workbench.report.pieces import absent as _absent
from workbench.report.pieces import escape as _e
from workbench.report.pieces import figure_pool, html_figure
from workbench.report.plots import (
    band_figure,
    band_zoom_figure,
    forest_figure,
    frf_overlay_figure,
    moment_error_figure,
    nyquist_figure,
    plot_moment_errors,
    plt,
    posterior_figure,
    prediction_figure,
    save_figure,
)
from workbench.report.shapes import shapes_section
from workbench.report.summary import SUMMARY_CSS, summary_box
from workbench.report.tables import Tables
from workbench.workflow.measured import campaign_label, mode_windows, nyquist_data
from workbench.workflow.runs import Run
from workbench.workflow.study import Prediction, Study

__all__ = ["render_report", "report_files", "SECTION_TITLES", "CSS", "html_table", "html_figure", "plt", "save_figure",
           "moment_error_figure", "plot_moment_errors"]

SECTION_TITLES = {
    "design": "Campaign and design",
    "frf": "Measured FRFs",
    "modes": "Extracted modes (circle fit)",
    "shapes": "Mode shapes and MAC: test against model",
    "nominal": "Nominal fit (Table 2 style)",
    "joints": "Joint models: moment matching and Bayesian",
    "posterior": "Posterior (emcee, arviz)",
    "accuracy": "SMR against Monte Carlo (Figure 11 style)",
    "band": "Stochastic FRF against the measured FRFs (Figure 12 style)",
    "section5": "Section 5: multi-bolt frames predicted from the one-bolt joint models",
    "done": "What was done",
    "limits": "Limits",
}

CSS = """
body{font-family:-apple-system,'Segoe UI',Helvetica,Arial,sans-serif;color:#1d2329;margin:0;background:#f3f4f6}
main{max-width:1180px;margin:0 auto;padding:18px 28px 48px;background:#fff}
h1{font-size:1.55em;margin:.4em 0 .2em}h2{font-size:1.3em;border-bottom:2px solid #1f4e79;padding-bottom:3px;
margin-top:2em;color:#1f4e79}h3{font-size:1.08em;margin-top:1.6em;color:#243b53}
.banner{padding:10px 14px;font-weight:700;border-radius:4px;margin:10px 0;font-size:1.05em}
.synthetic{background:#fff3cd;border:2px solid #c98a00;color:#6b4a00}
.real{background:#d9f2e3;border:2px solid #2f8f57;color:#1b5e36}
.badge{display:inline-block;padding:1px 7px;border-radius:3px;font-size:.78em;font-weight:700;vertical-align:middle}
.badge.synthetic{border-width:1px}.badge.real{border-width:1px}
.note{background:#eef3f8;border-left:4px solid #1f4e79;padding:6px 12px;margin:8px 0;font-size:.93em}
.absent{background:#f7f7f7;border-left:4px solid #999;padding:6px 12px;color:#444;font-style:italic}
figure{margin:10px 0 14px}figure img{max-width:100%;height:auto;border:1px solid #e1e4e8}
figcaption{font-size:.86em;color:#555;margin-top:3px}
.scroll{overflow-x:auto;margin:6px 0 12px}
table{border-collapse:collapse;font-size:.84em;font-variant-numeric:tabular-nums}
th,td{border:1px solid #d0d7de;padding:3px 7px;text-align:right;white-space:nowrap}
th{background:#eef1f4}td.l,th.l{text-align:left}td.w{white-space:normal;min-width:24em}
tr:nth-child(even) td{background:#fafbfc}
nav{font-size:.9em;columns:2;margin:8px 0}nav a{color:#1f4e79}
dl{display:grid;grid-template-columns:max-content auto;gap:2px 14px;font-size:.92em}dt{font-weight:600}dd{margin:0}
"""


# ----------------------------------------------------------------------------------- HTML pieces

def html_table(header: Sequence[str], rows: Iterable[Sequence[object]], left: int = 1, wrap: bool = False) -> str:
    """An HTML table; the first ``left`` columns are text (left-aligned), cells escaped; ``wrap``
    lets the last column's text wrap (long level descriptions) instead of scrolling.
    """
    def cell(tag: str, i: int, n: int, value: object) -> str:
        cls = "l w" if wrap and i == n - 1 else "l" if i < left else ""
        return f'<{tag} class="{cls.strip()}">{_e(value)}</{tag}>' if cls else f"<{tag}>{_e(value)}</{tag}>"

    head = "".join(cell("th", i, len(header), h) for i, h in enumerate(header))
    body = "".join("<tr>" + "".join(cell("td", i, len(row), c) for i, c in enumerate(row)) + "</tr>" for row in rows)
    return f'<div class="scroll"><table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table></div>'


def _badge(campaign) -> str:
    if campaign.synthetic:
        return '<span class="badge synthetic">SYNTHETIC - virtual test rig</span>'
    return '<span class="badge real">MEASURED - real test data</span>'


def _anchor(*parts: str) -> str:
    return "-".join("".join(c if c.isalnum() else "-" for c in p.lower()) for p in parts)


# -------------------------------------------------------------------------------- one campaign

def _design(study: Study, tables: Tables, prefix: str) -> str:
    c = study.campaign
    out = [f"<dl><dt>campaign</dt><dd>{_e(c.name)}</dd><dt>data</dt><dd>{_badge(c)}</dd>"
           f"<dt>source</dt><dd>{_e(c.source or '-')}</dd><dt>description</dt><dd>{_e(c.description or '-')}</dd>"
           f"<dt>frame</dt><dd>{_e(c.frame.name)} ({len(c.frame.joints)} joint(s): "
           f"{_e(', '.join(f'{j.name} [{j.group}]' for j in c.frame.joints))})</dd>"
           f"<dt>FRF quantity</dt><dd>{_e(c.quantity)} (reference: {_e(c.reference)})</dd></dl>"]
    if c.factors:
        out.append(tables.add(f"{prefix}factors", ["factor", "kind", "joint", "levels"],
                              [(f.name, f.kind, f.joint or "-", "; ".join(f"{k} = {v}" for k, v in f.levels.items()))
                               for f in c.factors], left=4, wrap=True))
    if c.design is not None:  # as the paper's Tables 5-7: one column per test
        design = c.design.astype(str)
        out.append(tables.add(f"{prefix}design", ["test", *design["test_id"]],
                              [(column, *design[column]) for column in design.columns if column != "test_id"],
                              left=len(design) + 1))
    else:
        out.append(_absent("no design table: the campaign publishes moments over tests that are not listed."))
    return "".join(out)


def _modes_section(study: Study, tables: Tables, prefix: str) -> str:
    ex = study.extraction
    if ex is None:
        return _absent(study.extraction_note)
    panels = nyquist_data(ex)
    f, z = ex.frequency_hz(), ex.damping_ratio()
    used = np.isfinite(f).sum(axis=0)
    flagged = ex.flag_counts()
    rows = []
    with np.errstate(invalid="ignore"):
        mean, std = np.nanmean(f, axis=0), np.nanstd(f, axis=0, ddof=1)
        zeta = np.nanmean(z, axis=0)
    for k, (lo, hi) in enumerate(ex.bands):
        rows.append((k + 1, (float(lo), float(hi)), float(mean[k]), float(std[k]), float(100 * std[k] / mean[k]),
                     float(100 * zeta[k]), f"{used[k]}/{len(ex.tests)}", int(flagged[k])))
    caption = (f"Circle fit of every mode on test {panels[0].test}, on the sensor with the largest combination "
               "weight: measured mobility (dots) and fitted modal circle with residual terms (line); red titles are "
               "flagged fits.")
    return (html_figure(nyquist_figure(panels), caption, "Nyquist plots of the circle fits") +
            tables.add(f"{prefix}modes", ["mode", "band (Hz)", "mean f (Hz)", "std f (Hz)", "CoV f (%)",
                                          "mean damping (%)", "tests used", "tests flagged"], rows,
                       ["", ".1f", ".2f", ".3f", ".3f", ".3f", "", ""], left=0) +
            '<p class="note">Sensors are combined per mode by fit quality; a mode whose combined fit is flagged '
            "weak, poor_circle or unresolved is left out of that test. Flagged tests (any flag, e.g. close_mode) are "
            "counted in the last column. Modes are paired with the model by order.</p>")


def _nominal_section(study: Study, tables: Tables, prefix: str) -> str:
    nom = study.moments.nominal
    moduli = ", ".join(f"{g}: E = {m / 1e9:.3g} GPa" for g, m in zip(nom.groups.groups, nom.moduli_pa))
    rows = [(int(m), int(mm), float(e), float(s), float(100 * r))
            for m, mm, e, s, r in zip(nom.modes, nom.model_modes, nom.measured_hz, nom.model_hz, nom.relative_error)]
    return (f'<p class="note">Eq. (1): joint moduli minimising the squared differences between the measured mean '
            f"frequencies and the nominal model's (joints at their mean, Nelder-Mead after a log scan): {_e(moduli)}; "
            f"RMS relative error {100 * nom.rms_relative_error:.2f} %.</p>" +
            tables.add(f"{prefix}nominal", ["mode", "model mode", "measured mean (Hz)", "model (Hz)", "error (%)"],
                       rows, ["", "", ".2f", ".2f", "+.2f"], left=0))


def _forest_rows(study: Study) -> list[dict]:
    rows = []
    post = study.posterior
    for g, src in study.joints.items():
        rows.append({"label": f"{g}: moments", "method": "moments", "modulus_gpa": src.youngs_modulus_pa / 1e9,
                     "modulus_ci": None if src.youngs_modulus_ci95 is None else np.array(src.youngs_modulus_ci95) / 1e9,
                     "cov": src.cov, "cov_ci": src.cov_ci95})
        if post is not None:
            i = post.groups.index(g)
            rows.append({"label": f"{g}: bayes", "method": "bayes", "modulus_gpa": post.youngs_modulus[i] / 1e9,
                         "modulus_ci": post.youngs_modulus_ci95[i] / 1e9, "cov": post.cov[i],
                         "cov_ci": post.cov_ci95[i]})
    return rows


def _pair(ci, scale: float = 1.0) -> tuple[float, float] | None:
    return None if ci is None else (float(ci[0]) * scale, float(ci[1]) * scale)


def _joints_section(study: Study, tables: Tables, prefix: str) -> str:
    fit = study.moments
    rows = _forest_rows(study)
    table = tables.add(f"{prefix}joints", ["group / estimator", "E (GPa)", "E 95 % interval (GPa)", "CoV (%)",
                                           "CoV 95 % interval (%)"],
                       [(r["label"], float(r["modulus_gpa"]), _pair(r["modulus_ci"]), 100 * float(r["cov"]),
                         _pair(r["cov_ci"], 100.0)) for r in rows], ["", ".4g", ".4g", ".3g", ".3g"])
    intervals = ("Moment-matching intervals: bootstrap of the tests carried through the linearised eq. (10)-(11) "
                 "(test-to-test sampling only, not model-form error)" if fit.mean_ci95 is not None else
                 "The moment matching gives no interval here (published moments only, or an estimate on a bound); "
                 "open markers")
    bayes = ("Bayesian: posterior median and equal-tailed 95 % interval (full likelihood of every test, emcee)."
             if study.posterior is not None else f"Bayesian estimator {study.bayes_note}.")
    moments = tables.add(f"{prefix}moments", ["mode", "measured mean (Hz)", "model mean (Hz)", "measured CoV (%)",
                                              "model CoV (%)"],
                         [(int(m), float(a), float(b), 100 * float(c), 100 * float(d))
                          for m, a, b, c, d in zip(fit.modes, fit.measured_mean_hz, fit.mean_hz, fit.measured_delta,
                                                   fit.delta)], ["", ".2f", ".2f", ".3f", ".3f"], left=0)
    return (html_figure(forest_figure(rows), "Mean joint modulus (GPa) and CoV (%) of each joint group, 95 % "
                        "intervals.",
                    "forest plot of the joint models") + table +
            f'<p class="note">{_e(intervals)}. {_e(bayes)} Moment matching: {fit.method} SMR forward model, '
            f"{fit.sweeps} sweep(s), {'converged' if fit.converged else 'NOT converged'}, {fit.evaluations} SMR "
            f"evaluations.</p><p>Measured moments against the identified model's (eq. 10-11 at the optimum):</p>" +
            moments)


def _posterior_name(name: str) -> tuple[str, float]:
    """A posterior parameter's label with its unit, and the factor from its natural unit (Pa, fraction)."""
    for prefix, label, unit, scale in (("youngs_modulus_", "E", "GPa", 1e-9), ("cov_", "CoV", "%", 100.0),
                                       ("sigma_", "sigma", "%", 100.0), ("common_error", "common s_u", "%", 100.0),
                                       ("discrepancy_scale", "discrepancy s_delta", "%", 100.0)):
        if name.startswith(prefix):
            return f"{label} {name[len(prefix):]}".rstrip() + f" ({unit})", scale
    return name, 1.0


def _posterior_section(study: Study, tables: Tables, prefix: str) -> str:
    post = study.posterior
    if post is None:
        return _absent(f"the Bayesian estimator was {study.bayes_note}.")
    fig = posterior_figure(post, load_arviz())
    rows = []
    values = np.concatenate([post.youngs_modulus, post.cov, post.sigma, post.error_scales])
    cis = np.concatenate([post.youngs_modulus_ci95, post.cov_ci95, post.sigma_ci95, post.error_scales_ci95])
    for name, v, ci, r, e, t in zip(post.parameter_names, values, cis, post.rhat, post.ess, post.autocorr_time):
        label, scale = _posterior_name(name)
        rows.append((label, float(v) * scale, _pair(ci, scale), float(r), float(e), float(t)))
    if post.discrepancy is not None and post.discrepancy_ci95 is not None:  # not sampled: no R-hat of its own
        rows += [(f"discrepancy mode{m} (%)", 100.0 * float(v), _pair(ci, 100.0), float("nan"), float("nan"),
                  float("nan")) for m, v, ci in zip(post.modes, post.discrepancy, post.discrepancy_ci95)]
    if post.sensitivity is not None and post.sensitivity_ci95 is not None:  # a factor exp(eps) on joint energies
        rows += [(f"joint energy error mode{m} (%)", 100.0 * float(v), _pair(ci, 100.0), float("nan"), float("nan"),
                  float("nan")) for m, v, ci in zip(post.modes, post.sensitivity, post.sensitivity_ci95)]
    status = ("converged" if post.converged else
              f"NOT converged (an R-hat above {RHAT_LIMIT} or a bulk ESS below {ESS_LIMIT}): intervals not final")
    return (html_figure(fig, "Posterior densities (95 % HDI, median) and pair plot of each group's mean modulus "
                        "(GPa) and CoV (%) (arviz).", "posterior plots") +
            tables.add(f"{prefix}posterior", ["parameter (unit)", "median (parameter's unit)",
                                              "95 % interval (parameter's unit)", "R-hat (-)", "bulk ESS (draws)",
                                              "autocorr. time (steps)"], rows,
                       ["", ".4g", ".4g", ".3f", ".0f", ".1f"]) +
            f'<p class="note">{post.walkers} walkers x {post.steps} steps after {post.burn} burn-in, seed {post.seed}, '
            f"acceptance {post.acceptance_fraction:.2f}, forward table error {post.forward_error:.1e}: {_e(status)}. "
            f"sigma modeK is mode K's relative measurement error, s_u the spread of a test's common relative shift "
            f"(temperature, mounting), s_delta that of the model's discrepancy per mode, discrepancy modeK mode K's "
            f"systematic relative error (its posterior over the sampled parameters), all in %.</p>")


def _accuracy_section(study: Study, tables: Tables, prefix: str) -> str:
    acc = study.accuracy
    if acc is None:
        return _absent(study.accuracy_note)
    mean_err, std_err = acc.errors_percent()
    label = "identified model"
    fig = moment_error_figure({label: (mean_err, std_err)}, {label: acc.reference_band_percent()})
    mc = acc.reference.moments
    se_mean, se_std = acc.reference.standard_errors()
    ref = acc.exact if acc.exact is not None else mc
    against = (f"the exact reference ({ref.method} Gauss rule over exact eigen-solves)" if acc.exact is not None
               else f"the {acc.samples}-sample Monte Carlo")
    header = ["mode", "ref. mean (Hz)", "ref. std (Hz)", "MC mean (Hz)", "MC mean SE (Hz)", "MC std (Hz)",
              "MC std SE (Hz)", *[f"{m} {what} error (%)" for m in mean_err for what in ("mean", "std")]]
    rows = [[k + 1, float(ref.mean_hz[k]), float(ref.std_hz[k]), float(mc.mean_hz[k]), float(se_mean[k]),
             float(mc.std_hz[k]), float(se_std[k]),
             *[float(e[m][k]) for m in mean_err for e in (mean_err, std_err)]]
            for k in range(ref.count)]
    formats = ["", ".3f", ".4f", ".2f", ".2f", ".3f", ".3f", *[f for _ in mean_err for f in ("+.3f", "+.2f")]]
    adaptive = acc.methods.get("adaptive")
    which = ("" if adaptive is None or adaptive.refined is None else
             " The adaptive strategy refined modes "
             f"{', '.join(str(k + 1) for k in np.flatnonzero(adaptive.refined)) or 'none'} by SMR2.")
    return (html_figure(fig, f"Relative errors of the frequency moments of the identified model against {against}; "
                    f"'mc' is the seeded Monte Carlo ({acc.samples} samples, seed {acc.reference.seed}) and grey its "
                    "3 standard errors; dotted: +-1 %.", "SMR accuracy bars") +
            tables.add(f"{prefix}accuracy", header, rows, formats, left=0) +
            '<p class="note">As in the paper\'s Figure 11 (Monte Carlo of 10 000 samples) and '
            "benchmarks/smr_accuracy.py: a Monte Carlo of a few hundred samples has standard errors of several % on "
            "the std, larger than the SMR errors, so the errors are read against the noise-free quadrature where it "
            f"is affordable (up to 4 random joints), the Monte Carlo being one more estimate.{_e(which)}</p>")


def _band_section(study: Study, tables: Tables, prefix: str) -> str:
    if study.band is None:
        return _absent(study.band_note)
    band = study.band
    ex = study.extraction
    assert ex is not None  # a band is computed only against measured FRFs (study_campaign)
    windows = mode_windows(band, ex.frequency_hz(), ex.mean_damping())
    return (html_figure(band_zoom_figure(band, ex.sets, windows),
                    "The band around each measured mode, at the sensor where it peaks highest (legend as below).",
                    "stochastic FRF band around each mode") +
            html_figure(band_figure(band, ex.sets),
                    f"FRF of the identified model: mean, 5-95 % band and envelope of |H| over {band.samples} joint "
                    f"samples (seed {band.seed}, exact modes tracked by MAC, measured mean damping per mode), over "
                    "the measured FRFs of every test (grey).", "stochastic FRF band") +
            '<p class="note">Modal superposition of the model\'s modes without residual terms: away from resonances, '
            "especially near antiresonances, the band is less trustworthy than at the peaks.</p>")


def _study_html(study: Study, number: int, tables: Tables) -> str:
    prefix = f"{number}_"
    sections = [("design", _design(study, tables, prefix))]
    if study.extraction is not None:
        caption = f"Measured |H| ({study.campaign.quantity}) of every test, one panel per sensor."
        sections.append(("frf", html_figure(frf_overlay_figure(study.extraction.sets), caption, "measured FRFs")))
    else:
        sections.append(("frf", _absent(study.extraction_note)))
    sections += [(key, part(study, tables, prefix)) for key, part in (
        ("modes", _modes_section), ("shapes", shapes_section), ("nominal", _nominal_section),
        ("joints", _joints_section), ("posterior", _posterior_section), ("accuracy", _accuracy_section),
        ("band", _band_section))]
    body = "".join(f'<h3 id="{_anchor(study.name, key)}">{number}.{i} {_e(SECTION_TITLES[key])}</h3>{content}'
                   for i, (key, content) in enumerate(sections, start=1))
    return f'<h2 id="{_anchor(study.name)}">{number}. {_e(study.name)} {_badge(study.campaign)}</h2>{body}'


# -------------------------------------------------------------------------------- section 5

def _prediction_html(pred: Prediction, number: int, sub: int, tables: Tables) -> str:
    c = pred.comparison
    measured = pred.extraction.frequency_hz()
    n = c.modes.size
    reference = c.predicted_mean_hz
    samples_pct = 100.0 * (pred.band.natural_hz[:, :n] / reference[None, :] - 1.0)
    measured_pct = 100.0 * (measured[:, :n] / reference[None, :] - 1.0)
    std_pct = 100.0 * c.predicted_std_hz / reference
    fig = prediction_figure(pred.band, pred.extraction.sets, 0, samples_pct, std_pct, measured_pct)
    used = np.isfinite(measured[:, :n]).sum(axis=0)
    rows = [(int(m), float(pm), float(mm), float(100 * e), float(ps), float(ms), float(r), f"{u}/{measured.shape[0]}")
            for m, pm, mm, e, ps, ms, r, u in zip(c.modes, c.predicted_mean_hz, c.measured_mean_hz, c.mean_rel_error,
                                                  c.predicted_std_hz, c.measured_std_hz, c.std_ratio, used)]
    named = {j.group for j in pred.campaign.frame.joints} | set(pred.campaign.frame.joint_names)
    kept = [j.name for j in pred.campaign.frame.joints if j.group not in pred.sources and j.name not in pred.sources]
    sources = tables.add(f"p{sub}_sources", ["joint group", "joints", "E (GPa)", "E 95 % interval (GPa)", "CoV (%)",
                                             "CoV 95 % interval (%)", "identified on"],
                         [(g, ", ".join(j.name for j in pred.frame.joints if j.group == g or j.name == g),
                           s.youngs_modulus_pa / 1e9, _pair(s.youngs_modulus_ci95, 1e-9), 100 * s.cov,
                           _pair(s.cov_ci95, 100.0), f"{s.campaign} ({s.method})")
                          for g, s in pred.sources.items() if g in named],
                         ["", "", ".4g", ".4g", ".3g", ".3g", ""], left=2, wrap=True)
    kept_note = f" Joints {', '.join(kept)} keep the frame file's model." if kept else ""
    return (f'<h3 id="{_anchor("section5", pred.name)}">{number}.{sub} {_e(pred.name)} {_badge(pred.campaign)}</h3>'
            f"<p>{_e(pred.campaign.name)}: {len(pred.extraction.tests)} tests. Joint models applied:{_e(kept_note)}</p>"
            + sources +
            html_figure(fig, f"Left: predicted FRF band ({pred.band.samples} samples, seed {pred.band.seed}) over the "
                    f"measured FRFs at sensor {pred.band.sensors[0]}. Right: per mode, the predicted spread (5-95 % "
                    "of the band's Monte Carlo frequencies, and the adaptive SMR mean +- std) against the measured "
                    "frequencies of every test, all in % of the predicted mean.", f"section 5 prediction {pred.name}") +
            tables.add(f"p{sub}_frequencies", ["mode", "predicted mean (Hz)", "measured mean (Hz)", "mean error (%)",
                                               "predicted std (Hz)", "measured std (Hz)", "std ratio (-)",
                                               "tests used"], rows,
                       ["", ".2f", ".2f", "+.2f", ".3f", ".3f", ".2f", ""], left=0) +
            '<p class="note">Predicted: adaptive SMR moments of the frame with the one-bolt joint models. Measured: '
            "mean and standard deviation (ddof 1, NaN-aware) of the circle-fit frequencies over the tests. "
            "std ratio = predicted / measured.</p>" +
            html_figure(band_zoom_figure(pred.band, pred.extraction.sets,
                                     mode_windows(pred.band, measured, pred.extraction.mean_damping())),
                    "The predicted band around each measured mode, at the sensor where it peaks highest.",
                    f"predicted band around each mode, {pred.name}"))


# ------------------------------------------------------------------------------------ the page

def _steps_table(run: Run, tables: Tables) -> str:
    """Every step's wall time; circle fits of several campaigns run in parallel processes, so their
    times overlap the run's "load and circle-fit" step instead of adding to it.
    """
    rows = [("(run)", s.name, s.detail, s.seed, float(s.wall_time_s)) for s in run.steps]
    items: list[Study | Prediction] = [*run.studies, *run.predictions]
    for item in items:
        rows += [(item.name, s.name, s.detail, s.seed, float(s.wall_time_s)) for s in item.steps]
    return tables.add("steps", ["campaign", "step", "detail", "seed", "wall time (s)"], rows, ["", "", "", "", ".2f"],
                      left=3)


def _limits(run: Run) -> str:
    items = []
    if any(s.campaign.synthetic for s in run.studies) or any(p.campaign.synthetic for p in run.predictions):
        items.append("Campaigns marked SYNTHETIC come from the workbench's virtual test rig (campaigns/README.md), "
                     "not from a laboratory: they check that the chain recovers what the rig put in, not that the "
                     "model fits a real frame.")
    items += [
        f"Monte Carlo sample counts are {run.samples} (the paper: 10 000 for Figure 11, 1 000 for Figures 14 and "
        "16): the reference's own standard errors are shown, and SMR errors below them are not resolved.",
        "The joint law is the paper's Gamma law (eq. 8-9); the rig's preload law is not Gamma, and the "
        "tests are a design, not a random sample, so 'CoV' is the spread over the design's levels.",
        "Measured and model modes are paired by order, not by MAC: a mode missed or swapped in the extraction "
        "shifts the pairing.",
        "Stochastic FRFs: modal superposition without residual terms, damping per mode from the measured mean "
        "(circle fit); modes above the measured ones take the last measured damping.",
    ]
    if run.predictions:
        items.append("Section 5 uses four_bolt_table6 (low amplitude): in four_bolt_table7 (high amplitude) mode 9 "
                     "scatters (campaigns/README.md). The four-bolt rig holds a locked-in compressive force in its "
                     "beam "
                     "(tightening sequence) that the frame file does not model: the prediction over-estimates the "
                     "measured means, most at high frequency, the misfit the paper's section 5.2 reports and "
                     "attributes to the tightening sequence.")
    if any(s.posterior is None for s in run.studies):
        items.append("Where the Bayesian estimator was not run, its reason is given in the study's joint-model "
                     "section; run `workbench report CAMPAIGN` (default 3000 steps) to add it.")
    return "<ul>" + "".join(f"<li>{_e(i)}</li>" for i in items) + "</ul>"


def render_report(run: Run, total_wall_s: float | None = None) -> str:
    """The report page of ``run`` (module notes): one self-contained HTML document (`report_files`'s index.html).

    Parameters
    ----------
    run : studies and predictions (`workbench.workflow.runs.report_run` or `demo_run`).
    total_wall_s : the whole command's wall time, s, shown in "what was done".
    """
    return report_files(run, total_wall_s)["index.html"]


def report_files(run: Run, total_wall_s: float | None = None, workers: int = 1) -> dict[str, str]:
    """The report's files: ``index.html`` and one CSV per table of the page (`workbench.report.tables`),
    file name -> text, for the command's output set.

    Parameters
    ----------
    run : studies and predictions (`workbench.workflow.runs.report_run` or `demo_run`).
    total_wall_s : the whole command's wall time, s, shown in "what was done".
    workers : processes drawing the figures while the page is built (`workbench.report.pieces.figure_pool`).
    """
    with figure_pool(workers) as pool:
        files = _page_files(run, total_wall_s)
        if pool is not None:
            files["index.html"] = pool.resolve(files["index.html"])
    return files


def _page_files(run: Run, total_wall_s: float | None) -> dict[str, str]:
    tables = Tables()
    summary = summary_box(run, tables)
    campaigns = [s.campaign for s in run.studies] + [p.campaign for p in run.predictions]
    synthetic = [c for c in campaigns if c.synthetic]
    if synthetic:
        banner = ('<div class="banner synthetic">SYNTHETIC - virtual test rig: '
                  f"{_e(', '.join(dict.fromkeys(campaign_label(c) for c in synthetic)))} "
                  "hold simulated data, not measurements.</div>")
    else:
        banner = ""
    real = [c for c in campaigns if not c.synthetic]
    if real:
        banner += ('<div class="banner real">MEASURED - real test data: '
                   f"{_e(', '.join(dict.fromkeys(campaign_label(c) for c in real)))}.</div>")
    toc, parts = [], []
    for n, study in enumerate(run.studies, start=1):
        toc.append(f'<a href="#{_anchor(study.name)}">{n}. {_e(study.name)}</a>')
        parts.append(_study_html(study, n, tables))
    n = len(run.studies)
    if run.predictions:
        n += 1
        toc.append(f'<a href="#section5">{n}. {_e(SECTION_TITLES["section5"])}</a>')
        parts.append(f'<h2 id="section5">{n}. {_e(SECTION_TITLES["section5"])}</h2>'
                     '<p>The paper identifies one stochastic model per joint family on the one-bolt frames (Table 4) '
                     "and predicts the two- and four-bolt frames with them (Figures 14 and 16). Here: the joint models "
                     "identified above (moment matching) on the frames below, against their measured FRFs and "
                     "circle-fit frequencies.</p>" +
                     "".join(_prediction_html(p, n, i, tables) for i, p in enumerate(run.predictions, start=1)))
    for key in ("done", "limits"):
        n += 1
        toc.append(f'<a href="#{key}">{n}. {_e(SECTION_TITLES[key])}</a>')
        if key == "done":
            total = "" if total_wall_s is None else f" Total wall time {total_wall_s:.1f} s."
            parts.append(f'<h2 id="done">{n}. {_e(SECTION_TITLES["done"])}</h2>'
                         f"<p>Seed {run.seed} for every random step (bootstrap, emcee, Monte Carlo, FRF band); "
                         f"{run.samples} Monte Carlo samples; emcee {run.bayes_steps} steps where run.{_e(total)} "
                         f"workbench {_e(__version__)}, Python {_e(platform.python_version())}, numpy "
                         f"{_e(np.__version__)}. The circle fits' times are measured in the processes that ran "
                         "them and overlap the run's load step.</p>" + _steps_table(run, tables))
        else:
            parts.append(f'<h2 id="limits">{n}. {_e(SECTION_TITLES["limits"])}</h2>' + _limits(run))
    page = ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>{_e(run.title)}</title>"
            f"<style>{CSS}{SUMMARY_CSS}</style></head><body><main><h1>{_e(run.title)}</h1>{banner}{summary}"
            "<p>Bolted-joint variability after Ghienne, Laurent &amp; Blanz&eacute;, MSSP 136 (2020) 106510: "
            "circle-fit extraction, joint identification (eq. 1, 10-11; Bayesian), propagation (SMR, eq. 5-7) and "
            f"stochastic FRFs. Units: moduli in GPa, frequencies in Hz, damping ratios and CoV in %; every table is "
            f"also a CSV file beside this page (linked below it).</p><nav>{'<br>'.join(toc)}</nav>{''.join(parts)}"
            "</main></body></html>\n")
    return {"index.html": page, **tables.files()}
