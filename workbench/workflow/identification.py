"""The identification of a campaign: what ``workbench identify`` computes and writes.

`identify_campaign` reads the campaign, extracts or reads its modes, pairs them with the frame's,
runs moment matching or the Bayesian identification, and builds ``identification.json`` (CONTRACTS.md
section 3) and, for bayes, ``posterior.nc``. It refuses what it cannot stand behind (an estimate at
its bound, chains that have not converged) unless ``allow_bounds``; the command line only parses,
writes the files it returns and prints the summary.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from pathlib import Path

from workbench.identify.bayes import Posterior, bayes_identify
from workbench.identify.data import check_moments, usable_modes
from workbench.identify.laplace import ERROR_TERMS
from workbench.identify.moments import MomentFit, moment_matching
from workbench.identify.pairing import pair_by_mac
from workbench.identify.record import ESS_LIMIT, RHAT_LIMIT, bound_failures, identification_record, sampler_diagnostics
from workbench.io.campaign import load_campaign
from workbench.io.outputs import json_text
from workbench.model.frame import Frame
from workbench.model.structure import structure_of
from workbench.model.tolerance import Tolerances
from workbench.progress import Progress
from workbench.workflow.measured import measured_modes

__all__ = ["IdentifyOptions", "Identified", "identify_campaign"]


@dataclass(frozen=True)
class IdentifyOptions:
    """``workbench identify``'s settings (its options' help says what each does)."""

    method: str
    count: int | None = None
    seed: int = 0
    steps: int = 3000
    max_steps: int = 12000
    errors: str = "full"
    tolerances: Tolerances | None = None
    allow_bounds: bool = False


@dataclass(frozen=True)
class Identified:
    """What `identify_campaign` found: the files to write (all or none), the record, the campaign's name and
    its data's source.
    """

    files: dict[str, str | bytes]
    record: dict
    campaign: str
    source: str


def identify_campaign(path: Path, options: IdentifyOptions, progress: Progress | None = None) -> Identified:
    """Identify the joints of the campaign at ``path`` (module docstring).

    Raises
    ------
    ValueError
        Bad input, a campaign bayes cannot use, an estimate at its bound or unconverged chains (unless
        ``options.allow_bounds``): one line naming the campaign and the cause.
    """
    terms = ERROR_TERMS[options.errors]
    if options.tolerances is not None and (options.method != "bayes" or not terms.discrepancy or terms.sensitivity):
        raise ValueError(f"{path}: --tolerances needs --method bayes with --errors full or discrepancy (the "
                         "tolerances enter beside the discrepancy term, without the sensitivity term)")
    campaign = load_campaign(path)
    if options.tolerances is not None and not isinstance(campaign.frame, Frame):
        raise ValueError(f"{path}: --tolerances: a matrix model has no members or materials to give tolerances to")
    data, dropped = usable_modes(measured_modes(campaign, options.count, "identify from"))
    if dropped:
        warnings.warn(f"{path}: modes {dropped} were extracted in fewer than 2 tests: left out "
                      "(modes_used in identification.json lists the modes used)", stacklevel=1)
    check_moments(data)  # refuse unusable moments before the method's own checks, as before any work
    if options.method == "bayes" and not data.has_tests:
        raise ValueError(f"{path}: bayes needs every test's frequencies (modes.csv or FRFs); this "
                         "campaign has only published moments (moments.csv): use --method moments")
    model = structure_of(campaign.frame)
    data = pair_by_mac(model, data)  # with measured shapes, mode i is the model mode of its shape, not the i-th
    start = time.perf_counter()
    files: dict[str, str | bytes] = {}
    fit: MomentFit | Posterior
    if options.method == "moments":
        fit = moment_matching(model, data, seed=options.seed)
    else:
        from workbench.workflow.posterior import POSTERIOR_FILE, posterior_netcdf

        fit = posterior = bayes_identify(model, data, seed=options.seed, steps=options.steps,
                                         max_steps=max(options.max_steps, options.steps),
                                         errors=terms, progress=progress,
                                         tolerances=options.tolerances)
        files[POSTERIOR_FILE] = posterior_netcdf(posterior)  # written with the rest: all files or none
    record = identification_record(campaign.name, options.method, campaign.frame, fit, data.modes,
                                   time.perf_counter() - start)
    _refuse_what_it_cannot_stand_behind(path, options, record, fit)
    files["identification.json"] = json_text(record)
    return Identified(files, record, campaign.name, data.source)


def _refuse_what_it_cannot_stand_behind(path: Path, options: IdentifyOptions, record: dict,
                                        fit: MomentFit | Posterior) -> None:
    """An estimate at its bound or unconverged chains: an error, or with ``allow_bounds`` a flag and a warning
    (``record`` gains the sampler's diagnostics and error terms).
    """
    failures = bound_failures(record, fit)
    if failures and not options.allow_bounds:
        raise ValueError(f"{path}: failed identification, {failures[0]}"
                         + (f" (and {len(failures) - 1} more joints)" if len(failures) > 1 else "")
                         + ": the data do not place it; --allow-bounds writes it flagged \"at_bound\": true")
    for failure in failures:
        warnings.warn(f"{path}: {failure} (written with \"at_bound\": true)", stacklevel=1)
    diagnostics = sampler_diagnostics(fit)
    if diagnostics is None or not isinstance(fit, Posterior):
        return
    record["diagnostics"] = diagnostics
    record["errors"] = fit.error_records()
    if not diagnostics["converged"]:
        unsettled = (f"the chains have not converged in {fit.steps} steps (max R-hat "
                     f"{diagnostics['rhat_max']:.3f}, limit {RHAT_LIMIT}; min ESS {diagnostics['ess_min']:.0f}, "
                     f"limit {ESS_LIMIT})")
        if not options.allow_bounds:
            raise ValueError(f"{path}: failed identification, {unsettled}: raise --max-steps, or "
                             "--allow-bounds writes it with \"converged\": false")
        warnings.warn(f"{path}: {unsettled}: identification.json says \"converged\": false", stacklevel=1)
