"""Where the modes are: bands around the resonance peaks, and the bands that hold two modes.

`find_mode_bands` finds the peaks across sensors and tests (peak detection; a user may give their own
bands instead), and `split_bands` lists a band twice where a two-pole fit
(`workbench.extraction.multimode`) finds two modes under one peak in most tests, and `track_bands` follows each
mode from test to test (a joint that softens with the excitation level moves a mode by a few percent between
levels: the bands found across all tests then hold it at two places). `workbench.extraction.modes` fits the
bands.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import find_peaks

from workbench.extraction.circlefit import MIN_BAND_POINTS, _check_frequency, _check_frfs, noise_level
from workbench.extraction.multimode import second_mode
from workbench.tasks import Mapper, serial_mapper

__all__ = ["find_mode_bands", "split_bands", "track_bands", "peak_start", "MOVE_LIMIT"]

OPEN_SIDE_DROP = 0.05  # decades (1 dB): a peak's side cut off by the band must fall this much (`_prominences`)
OPEN_SIDE_LINES = 4  # lines, at least, on that side
MOVE_LIMIT = 0.1  # a mode moves less than 10 % between tests (3 % is a strongly softening joint); farther is another


def _half_power_edges(s: np.ndarray, k: int) -> tuple[float, float]:
    """Fractional indices where ``s`` first falls below ``s[k] / sqrt(2)`` on each side of ``k``."""
    level = s[k] / np.sqrt(2.0)
    left = np.nonzero(s[:k] < level)[0]
    right = np.nonzero(s[k + 1:] < level)[0]
    if left.size:
        i = left[-1]
        lo = i + (level - s[i]) / (s[i + 1] - s[i])
    else:
        lo = 0.0
    if right.size:
        j = k + 1 + right[0]
        hi = j - 1 + (s[j - 1] - level) / (s[j - 1] - s[j])
    else:
        hi = float(s.size - 1)
    return float(lo), float(hi)


def _prominences(log_s: np.ndarray, peaks: np.ndarray, props: dict) -> np.ndarray:
    """The peaks' prominences (decades), a side cut off by the measured band not counted.

    `scipy.signal.peak_prominences` bounds a peak by the lowest point on each side up to a higher peak, or up
    to the band's end where there is none: a resonance near the band's top whose curve the band cuts before it
    falls has too little prominence on that side (a single mode 1.5 % below the top with 1.4 % damping falls
    0.17 decades there, half the 0.3 asked; a dashpot's 1232 Hz mode below a 1250 Hz top fell 0.09 in a
    campaign's summary, the modes beyond the band holding it up). A side with no higher point is taken as cut
    off, so such a peak is measured on its other side, if the cut side falls by `OPEN_SIDE_DROP` over at least
    `OPEN_SIDE_LINES` lines: the band then holds the resonance's top (a single mode's curve falls that much half
    a half-power half-width past its peak), not the rising flank of a mode beyond it with a last line lower by
    noise. The rule reads every peak with one open side so, wherever it lies: in a measured FRF that is a
    resonance near an end of the band (a curve that never again falls to the valley before a peak, yet never
    rises above it, holds no second valley either). A peak open on both sides, the highest, keeps scipy's
    prominence.
    """
    prominences = np.asarray(props["prominences"], float).copy()
    if peaks.size == 0:
        return prominences
    left_max = np.maximum.accumulate(log_s)  # the highest point up to each line
    right_max = np.maximum.accumulate(log_s[::-1])[::-1]
    last = log_s.size - 1
    for i, k in enumerate(peaks):
        left_open = left_max[k - 1] <= log_s[k] if k > 0 else True
        right_open = right_max[k + 1] <= log_s[k] if k < last else True
        if right_open and not left_open and last - k >= OPEN_SIDE_LINES \
                and log_s[k] - log_s[k + 1:].min() >= OPEN_SIDE_DROP:
            prominences[i] = log_s[k] - log_s[props["left_bases"][i]]
        elif left_open and not right_open and k >= OPEN_SIDE_LINES and log_s[k] - log_s[:k].min() >= OPEN_SIDE_DROP:
            prominences[i] = log_s[k] - log_s[props["right_bases"][i]]
    return prominences


def find_mode_bands(frequency_hz, frfs, *, count: int | None = None, min_prominence: float = 0.3,
                    min_snr: float = 10.0, max_damping: float = 0.1, width_factor: float = 4.0,
                    min_lines: int = 4,
                    f_min: float = 0.0, f_max: float = np.inf) -> list[tuple[float, float]]:
    """Frequency bands around the resonance peaks seen across sensors and tests.

    The summary function is ``S(f) = mean_curves |H(f)| / sigma`` with ``sigma`` each curve's
    `noise_level` (so no sensor dominates and S reads in noise levels); peaks of ``log10 S`` with a
    prominence of at least ``min_prominence`` decades (a side the band's end cuts off not counted,
    `_prominences`) and a height of at least ``min_snr`` noise
    levels are kept (`scipy.signal.find_peaks`), the ``count`` most prominent if given. Each band
    is the peak +- ``width_factor`` half-power half-widths of S (at least ``min_lines`` lines each
    side), cut at the minimum of S between neighbouring peaks so that bands do not overlap (unless
    the cut leaves fewer than `MIN_BAND_POINTS` lines: such a band is widened back, and two peaks
    that close will be flagged ``"close_mode"`` by `fit_modes`). Bands are a suggestion: `fit_modes`
    accepts the user's own.

    Parameters
    ----------
    frequency_hz : (n_freq,) Hz, strictly increasing.
    frfs : (n_curves, n_freq) or (n_freq,) complex FRFs (any quantity; peaks of |H|).
    count : keep at most this many peaks, the most prominent.
    min_prominence : decades of ``log10 S``.
    min_snr : minimum peak height of S, in noise levels (modes hidden in noise are not reported).
    max_damping : peaks whose half-power width exceeds ``2 max_damping f`` are broad humps between
        antiresonances, not modes, and are dropped.
    width_factor : band half-width in half-power half-widths.
    min_lines : minimum lines each side of the peak.
    f_min, f_max : Hz, peaks outside are ignored.

    Returns
    -------
    list of (f_lo, f_hi) in Hz, increasing.
    """
    f = _check_frequency(frequency_hz)
    h = _check_frfs(frfs, f.size)
    s = _summary(h)
    log_s = np.log10(np.maximum(s, np.finfo(float).tiny))
    peaks, props = find_peaks(log_s, prominence=0.0, height=np.log10(min_snr))
    prominences = _prominences(log_s, peaks, props)
    prominent = prominences >= min_prominence
    peaks, prominences = peaks[prominent], prominences[prominent]
    keep = (f[peaks] >= f_min) & (f[peaks] <= f_max) & (f[peaks] > 0)
    lines = np.arange(f.size, dtype=float)
    edges = {int(k): _half_power_edges(s, int(k)) for k in peaks}
    narrow = np.array([np.interp(edges[k][1], lines, f) - np.interp(edges[k][0], lines, f)
                       <= 2.0 * max_damping * f[k] for k in peaks], dtype=bool)
    keep &= narrow
    peaks, prominence = peaks[keep], prominences[keep]
    if count is not None and peaks.size > count:
        peaks = np.sort(peaks[np.argsort(prominence)[::-1][:count]])
    bands = []
    for n, k in enumerate(peaks):
        lo, hi = edges[int(k)]
        half = max(width_factor * 0.5 * (hi - lo), float(min_lines))
        i_lo, i_hi = k - half, k + half
        if n > 0:  # cut at the valley between neighbouring peaks
            i_lo = max(i_lo, peaks[n - 1] + int(np.argmin(s[peaks[n - 1]:k + 1])))
        if n < peaks.size - 1:
            i_hi = min(i_hi, k + int(np.argmin(s[k:peaks[n + 1] + 1])))
        need = 0.5 * (MIN_BAND_POINTS - 1)  # a cut band keeps enough lines (its mode will be "close")
        i_lo, i_hi = min(i_lo, k - need), max(i_hi, k + need)
        i_lo, i_hi = max(i_lo, 0.0), min(i_hi, f.size - 1.0)
        bands.append((float(np.interp(i_lo, lines, f)), float(np.interp(i_hi, lines, f))))
    return bands


def split_bands(frequency_hz: list, frfs: list, quantity: str, bands,
                mapper: Mapper | None = None) -> list[tuple[float, float]]:
    """The bands again, a band listed twice where it holds two modes.

    In every test, the curves of each band are fitted with one pole and with two
    (`workbench.extraction.multimode.second_mode`: poles common to the test's curves); a band whose
    second pole is accepted in at least half of the tests holds two modes, and is listed twice
    (band k and k + 1: its lower and upper mode, `fit_modes` then fits both at once). Where the band
    does not, the same is tried on the band widened by half its width each side (up to its
    neighbours): `find_mode_bands` drops a peak of less than ``min_prominence`` on the shoulder of
    a larger one (measured: 0.2 decades for a pair 3 % apart at 0.5 % damping), and its band then
    misses that mode; the widened band is the one listed twice.

    Parameters
    ----------
    frequency_hz : per test, (n_freq,) Hz.
    frfs : per test, (n_curves, n_freq) complex FRFs in the unit of ``quantity``.
    quantity : receptance, mobility or accelerance.
    bands : (f_lo, f_hi) Hz per band, increasing (`find_mode_bands`).
    mapper : runs the bands' votes (`workbench.tasks.Mapper`; each band is one task, its votes
        independent of the others'); default, one after the other here. The bands are the same either way.

    Returns
    -------
    list of (f_lo, f_hi), increasing, each band once or twice.
    """
    bands = [(float(lo), float(hi)) for lo, hi in bands]
    noise = [noise_level(h) for h in frfs]  # each test's, once: not once per band and vote
    tasks = []
    for n, (lo, hi) in enumerate(bands):
        floor = bands[n - 1][1] if n > 0 else -np.inf
        ceiling = bands[n + 1][0] if n + 1 < len(bands) else np.inf
        tasks.append(((lo, hi), (max(lo - 0.5 * (hi - lo), floor), min(hi + 0.5 * (hi - lo), ceiling))))
    run = mapper or serial_mapper()
    voted = run(_band_vote, tasks, "band votes", (frequency_hz, frfs, noise, quantity))
    return [band for listed in voted for band in listed]


def _band_vote(shared: tuple, task: tuple) -> list[tuple[float, float]]:
    """One band of `split_bands`: ``task = (band, widened band)``, ``shared = (frequency_hz, frfs, noise,
    quantity)``; the band listed twice, or the widened band twice, where either holds two modes, else once.
    """
    frequency_hz, frfs, noise, quantity = shared
    for band in task:
        if _holds_two(frequency_hz, frfs, noise, quantity, band):
            return [band, band]
    return [task[0]]


def _holds_two(frequency_hz: list, frfs: list, noise: list, quantity: str, band: tuple[float, float]) -> bool:
    """True when at least half of the tests accept a second pole in ``band`` (`split_bands`; ``noise``: each
    test's `noise_level`); the tests are asked in turn until the vote is decided (each is two least-squares
    pole fits).
    """
    voters = []
    for f, h, sigma in zip(frequency_hz, frfs, noise):
        f, h = np.asarray(f, float), np.atleast_2d(h)
        inside = (f >= band[0]) & (f <= band[1])
        if inside.sum() >= MIN_BAND_POINTS and f[inside][0] > 0.0:
            voters.append((f, h, sigma, inside))
    needed = (len(voters) + 1) // 2   # ayes for 2 * ayes >= len(voters)
    ayes = noes = 0
    for f, h, sigma, inside in voters:
        if ayes >= needed or noes > len(voters) - needed:
            break
        accepted = second_mode(f, h, band, quantity, sigma, peak_start(f[inside], h[:, inside]))[2]
        ayes, noes = ayes + accepted, noes + (not accepted)
    return bool(voters) and ayes >= needed


def peak_start(f: np.ndarray, h: np.ndarray) -> tuple[float, float]:
    """(frequency Hz, damping) of the summed |H| peak of a band, from its half-power width."""
    s = np.sum(np.abs(h) / noise_level(h)[:, None], axis=0)
    k = int(np.argmax(s))
    lo, hi = _half_power_edges(s, k)
    lines = np.arange(f.size, dtype=float)
    width = float(np.interp(hi, lines, f) - np.interp(lo, lines, f))
    return float(f[k]), float(np.clip(width / (2.0 * f[k]), 1e-4, 0.1))


def track_bands(frequency_hz: list, frfs: list, bands: list[tuple[float, float]]) -> tuple[
        list[tuple[float, float]], list[list[tuple[float, float]]]]:
    """Each mode's band in each test: moved onto the test's own peak, and one mode seen at two places merged.

    The bands found across every test sit on the peaks of their summary. A mode that moves between tests by more
    than its band's half-width (a joint softening with the excitation level: 1.5-3 % between two levels at
    0.4 % damping) has its peak at one edge of the band, or two bands, each holding it in some tests only.
    Per test, each band's search window runs from the midpoint with its lower neighbour's centre to the midpoint
    with its upper one; the test holds the mode there when the largest of its summary ``mean |H| / noise`` is
    inside the window and at least ``sqrt 2`` times the window's ends (a half-power peak). Then:

    - neighbouring bands that no test holds two of, each held by some test and within `MOVE_LIMIT` of each
      other, are one mode: merged;
    - each test's band is moved (its width kept) to centre on the test's own peak, slid back inside its window
      or its bands (whichever is wider) where it would leave them.

    A band listed twice (`split_bands`: two modes under one peak) is left as it is.

    Parameters
    ----------
    frequency_hz : per test, (n_freq,) Hz.
    frfs : per test, (n_curves, n_freq) complex FRFs.
    bands : (f_lo, f_hi) Hz per band, increasing, a band holding two modes listed twice.

    Returns
    -------
    The bands, merged (a merged band spans its places), and per test its bands in the same order.
    """
    bands = [(float(lo), float(hi)) for lo, hi in bands]
    if not bands:
        return [], [[] for _ in frfs]
    axes = [_check_frequency(f) for f in frequency_hz]
    summaries = [_summary(_check_frfs(h, f.size)) for f, h in zip(axes, frfs)]
    twice = [bands.count(b) > 1 for b in bands]
    centres = [_centre(axes, summaries, b) for b in bands]
    widths = [hi - lo for lo, hi in bands]
    windows = [(0.5 * (centres[k - 1] + centres[k]) if k > 0 else bands[k][0] - 0.5 * widths[k],
                0.5 * (centres[k] + centres[k + 1]) if k + 1 < len(bands) else bands[k][1] + 0.5 * widths[k])
               for k in range(len(bands))]
    peaks = np.array([[np.nan if twice[k] else _own_peak(f, s, windows[k]) for k in range(len(bands))]
                      for f, s in zip(axes, summaries)])
    held = ~np.isnan(peaks)
    groups: list[list[int]] = [[0]]
    for k in range(1, len(bands)):
        group = groups[-1]
        in_group = held[:, group].any(axis=1)
        one_mode = (not twice[k] and not twice[group[-1]] and in_group.any() and held[:, k].any()
                    and not (in_group & held[:, k]).any() and centres[k] <= (1.0 + MOVE_LIMIT) * centres[group[0]])
        if one_mode:
            group.append(k)
        else:
            groups.append([k])
    merged = [(bands[g[0]][0], bands[g[-1]][1]) for g in groups]
    per_test = []
    for row in peaks:
        own = []
        for g, span in zip(groups, merged):
            found = [k for k in g if not np.isnan(row[k])]
            if not found:  # the test holds no peak of this mode: the whole span, the fit flags what it finds
                own.append(span)
                continue
            k = found[0]
            floor = min(windows[g[0]][0], span[0])
            ceiling = max(windows[g[-1]][1], span[1])
            lo, hi = bands[k][0] + row[k] - centres[k], bands[k][1] + row[k] - centres[k]
            back = max(hi - ceiling, 0.0) - max(floor - lo, 0.0)  # slid back inside, not cut (its lines kept)
            own.append((max(lo - back, floor), min(hi - back, ceiling)))
        per_test.append(own)
    return merged, per_test


def _summary(h: np.ndarray) -> np.ndarray:
    """(n_freq,) ``mean_curves |H| / sigma``, ``sigma`` each curve's `noise_level`: the peaks in noise levels."""
    return np.mean(np.abs(h) / noise_level(h)[:, None], axis=0)


def _centre(axes: list[np.ndarray], summaries: list[np.ndarray], band: tuple[float, float]) -> float:
    """Hz: the peak of the tests' summed summary in ``band`` (the tests on one axis, else the first test's)."""
    f = axes[0]
    same = all(np.array_equal(g, f) for g in axes)
    total = np.sum(summaries, axis=0) if same else summaries[0]
    inside = (f >= band[0]) & (f <= band[1])
    if not inside.any():
        return 0.5 * (band[0] + band[1])
    return float(f[inside][np.argmax(total[inside])])


def _own_peak(f: np.ndarray, s: np.ndarray, window: tuple[float, float]) -> float:
    """Hz: one test's half-power peak inside ``window`` (`track_bands`), NaN when it has none there."""
    inside = np.flatnonzero((f >= window[0]) & (f <= window[1]))
    if inside.size < 3:
        return float("nan")
    values = np.where(np.isfinite(s[inside]), s[inside], -np.inf)
    k = int(np.argmax(values))
    if k in (0, values.size - 1) or not values[k] >= np.sqrt(2.0) * max(values[0], values[-1]):
        return float("nan")
    return float(f[inside][k])
