"""A candidate's leave-one-mode-out predictive density of the frequency means: the score it is ranked by.

Leave one mode out (`workbench.diagnose.fitting`): the fit that did not see mode ``k`` predicts it. Under the
campaign's covariance (`workbench.diagnose.observations.Observations.joint_covariance`) the modes' errors are
correlated: a common shift, the frame's geometry and sections, the joints' scatter move every mode at once. So
what fit ``k`` predicts for mode ``k`` is a Gaussian *conditional* on the other modes' residuals under that
same fit: its mean is the model's prediction plus the share of the others' residuals the covariance carries
to mode ``k`` (a common shift seen in nine modes is expected in the tenth), and its covariance is the
conditional one,

    e_k = r_k - W_k,-k W_-k,-k^-1 r_-k = (P_kk)^-1 (P r)_k,    S_k = (P_kk)^-1,    P = W^-1

(the precision form: Sundararajan & Keerthi 2001, Rasmussen & Williams 2006 eq. (5.12)), ``r`` the relative
residuals of fit ``k``'s predictions of every mean and ``W`` the covariance widened by that fit's form error
(`FORM_SD` of the change it predicts, one error per mode shared by the excitation levels). The score is minus
twice the summed log predictive density, ``sum_k e_k' S_k^-1 e_k + log det S_k``, up to a constant every
candidate shares: returned as the chi-square part and the log determinants less those of the plain
covariance.

Through seed 29 the held-out predictions of mode ``k`` by fit ``k`` were gathered into one vector and its joint
chi-square taken under the full covariance. That vector is no model's prediction (each mean from another fit),
and its chi-square could fall far below the candidate's own in-sample minimum: on validation seed 28, case 157
(a support giving way in two dofs), a rotational spring whose best in-sample fit was the nominal model
(chi-square 36.6) scored 15.7 held out and ranked first, while the translational spring that fitted at 10.3
ranked eleventh. With modes independent (the covariance block-diagonal in the modes) the two are the same.
"""

from __future__ import annotations

import numpy as np

from workbench.diagnose.observations import FORM_SD, Observations

__all__ = ["frequency_score"]


def frequency_score(obs: Observations, predicted_hz: np.ndarray, reference_hz: np.ndarray) -> tuple[float, float]:
    """``(chi2, log_det)`` of the leave-one-mode-out predictive density (module docstring).

    Parameters
    ----------
    obs : the observations, their covariance and discrepancy.
    predicted_hz : (n_modes, n_cond, n_modes) Hz, row ``k`` the means predicted by the fit that left mode ``k``
        out; or (n_cond, n_modes), one prediction for every mode left out (a candidate with no frequency
        parameter, the nominal model).
    reference_hz : (n_cond, n_modes) Hz, the nominal model's means: the form error is ``FORM_SD`` of the change
        from them.

    Returns
    -------
    ``chi2 = sum_k e_k' S_k^-1 e_k`` and ``log_det = sum_k log det S_k - log det S_k(plain)``, the plain
    covariance being the one without the form's error; inf and 0 where a prediction of a present mean is not
    finite.
    """
    n_modes = obs.frequency_hz.shape[1]
    if predicted_hz.ndim == 2:
        predicted_hz = np.broadcast_to(predicted_hz, (n_modes, *predicted_hz.shape))
    present, cov = obs.joint_covariance(np.ones(n_modes, bool))
    mode = np.nonzero(present)[1]
    same_mode = mode[:, None] == mode[None, :]
    plain = np.linalg.inv(cov)
    chi2, log_det = 0.0, 0.0
    for k in range(n_modes):
        block = mode == k
        if not block.any():
            continue
        r = (predicted_hz[k] / obs.frequency_hz - 1.0)[present]
        extra = (FORM_SD * (predicted_hz[k] / reference_hz - 1.0))[present]
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(extra))):
            return float("inf"), 0.0
        precision = np.linalg.inv(cov + np.outer(extra, extra) * same_mode)
        p_kk = precision[np.ix_(block, block)]
        pr = precision[block] @ r
        chi2 += float(pr @ np.linalg.solve(p_kk, pr))
        # log det S_k = -log det P_kk
        log_det += float(np.linalg.slogdet(plain[np.ix_(block, block)])[1] - np.linalg.slogdet(p_kk)[1])
    return chi2, log_det
