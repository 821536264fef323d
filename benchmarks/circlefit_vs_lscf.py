"""Circle fit (workbench) side by side with a peer tool, sdypy-EMA (LSCF poles + LSFD constants).

Run from the repository root: ``python benchmarks/circlefit_vs_lscf.py``; needs the benchmark extra
(``pip install -e .[bench]`` or ``pip install sdypy-EMA``) and, for the real data sets,
``/work/shared/data/real`` (``--real-root``; skipped with a note when absent).

Data sets, the same FRFs for both tools:

1. synthetic, well separated: 100 Hz / 3 %, 250 Hz / 1 %, 600 Hz / 0.1 %, four sensors (receptance
   constants ``A_r = 100 zeta_r`` times a shape factor per sensor, so the accelerance peaks are
   comparable), accelerance on 0-1250 Hz at 0.25 Hz, 40 dB SNR per curve, ``--seeds`` noise draws;
2. synthetic, close pair: 240 Hz and 250 Hz at 1 % (10 Hz apart = 2 half-power bandwidths), four
   sensors, same grid and noise: where a single-mode method is expected to lose;
3. UNESP-BERT, random excitation at six shaker levels 0.05-0.30 V, accelerometers acc1..acc4 over the
   shaker voltage, 0.0625-110 Hz: modes 1 (about 18.7 Hz) and 2 (about 98 Hz);
4. Brake-Reuss beam, force-controlled stepped sine at four force levels, 41 lines 79.2-81.2 Hz at
   0.05 Hz, drive-point accelerance: the first bending mode near 80 Hz.

Circle fit: `find_mode_bands` + `split_bands` (synthetic: per noise draw; UNESP: once over all levels
via `extract_tests`; Brake-Reuss: the whole 41-line band) then `fit_modes` + `combine` (weighted over
sensors; a band listed twice is fitted with two common poles, `workbench.extraction.multimode`).
Times include the band search. For the real data the tables give the circle fit's 95 % damping
interval (`ModeEstimate.damping_ci95`) and whether the LSCF damping lies inside it.

sdypy-EMA (non-interactive path, as its docs show for scripted use): ``Model(frf, freq, lower, upper,
pol_order_high, frf_form)``, ``get_poles('lscf')`` (one common-denominator LSCF over all sensors, orders
2..2 pol_order_high), ``select_closest_poles(approx)`` (stable poles: frequency within 0.1 % and
damping within 5 % of the previous order; the stable pole nearest to each ``approx``, refined over
shrinking windows of ``f_window`` Hz), ``get_constants('lsfd')`` (modal constants and residuals; its
reconstruction error is printed as a check). The ``approx`` frequencies are the |FRF| peaks inside our
bands (the same starting information for both tools); ``f_window`` is kept below half the distance
to the neighbouring mode and below the data span. Its time covers Model + poles + selection +
constants. Note: sdypy-EMA's LSCF zero-pads the FRF from 0 Hz up to the first line and cuts the line
at ``upper`` (the Brake-Reuss fit uses 40 of the 41 lines).

Prints one table per data set, the times, the trends on the real data and a verdict.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("TQDM_DISABLE", "1")  # sdypy-EMA's stabilization always draws a progress bar

import argparse  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from importlib.metadata import version  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.stats import spearmanr  # noqa: E402

from workbench.extraction.modes import combine, extract_tests, find_mode_bands, fit_modes, split_bands  # noqa: E402
from workbench.io.campaign import frf_set  # noqa: E402
from workbench.io.real_data import import_brake_reuss, import_unesp_bert  # noqa: E402
from workbench.model.modal import add_noise, modal_superposition  # noqa: E402

FRAMES = Path(__file__).resolve().parents[1] / "frames"  # the real data sets' nominal models

try:
    from sdypy import EMA
except ImportError as exc:  # a benchmark-only dependency
    raise SystemExit(f"sdypy-EMA is needed for this benchmark: pip install sdypy-EMA ({exc})") from None

REAL_ROOT = Path("/work/shared/data/real")
SNR_DB = 40.0
RESOLUTION_HZ = 0.25
F_MAX = 1250.0
SHAPES = np.array([[1.0, 1.0, 1.0],      # per sensor, multiplies A_r = 100 zeta_r
                   [0.8, -0.6, 0.9],
                   [0.5, 0.9, -0.7],
                   [-0.3, 0.7, 0.6]])
SYNTHETIC = {
    "well separated": dict(natural_hz=(100.0, 250.0, 600.0), damping=(0.03, 0.01, 0.001),
                           lscf=dict(lower=20.0, upper=F_MAX, pol_order_high=30)),
    "close pair, automatic bands": dict(natural_hz=(240.0, 250.0), damping=(0.01, 0.01),
                                        lscf=dict(lower=20.0, upper=F_MAX, pol_order_high=30)),
    # the user's bands, split halfway between the two modes (find_mode_bands may see one peak only)
    "close pair, user bands": dict(natural_hz=(240.0, 250.0), damping=(0.01, 0.01), bands=[(230.0, 245.0), (245.0, 260.0)],
                                   lscf=dict(lower=20.0, upper=F_MAX, pol_order_high=30)),
}
UNESP_LSCF = dict(lower=5.0, upper=110.0, pol_order_high=40)
BRB_LSCF = dict(pol_order_high=16)
ORDER_SWEEP = (8, 16, 24, 32, 40)  # sensitivity of the LSCF pick to the model order (real data)


# --------------------------------------------------------------------------------------------
# the two tools

def peak_frequencies(f: np.ndarray, frfs: np.ndarray, bands) -> list[float]:
    """|FRF| peak inside each band (each curve scaled by its maximum): the starting frequencies."""
    s = np.sum(np.abs(frfs) / np.abs(frfs).max(axis=1, keepdims=True), axis=0)
    out = []
    for lo, hi in dict.fromkeys(bands):  # a band listed twice (two modes) still has one peak
        inside = np.nonzero((f >= lo) & (f <= hi))[0]
        out.append(float(f[inside[np.argmax(s[inside])]]))
    return out


def circle(f: np.ndarray, frfs: np.ndarray, quantity: str, bands=None):
    """Circle fit: bands (found if None), fit every curve, combine; (bands, estimates, seconds)."""
    start = time.perf_counter()
    if bands is None:  # as extract_tests: a band holding two modes is listed twice
        bands = split_bands([f], [frfs], quantity, find_mode_bands(f, frfs))
    estimates = [combine(row) for row in fit_modes(f, frfs, quantity, bands)]
    return bands, estimates, time.perf_counter() - start


def lscf(f: np.ndarray, frfs: np.ndarray, quantity: str, approx: list[float], *, lower: float, upper: float,
         pol_order_high: int) -> dict:
    """sdypy-EMA LSCF + closest stable poles + LSFD. Frequencies (Hz) and damping ratios per
    ``approx`` (NaN where no stable pole was found), LSFD reconstruction error, seconds."""
    gaps = np.diff(sorted(approx)) if len(approx) > 1 else np.array([np.inf])
    f_window = float(min(50.0, 0.5 * gaps.min(), 0.5 * min(approx), f[-1] - f[0]))
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # clamping notes on 'upper' and numpy warnings on rejected poles
        model = EMA.Model(frf=frfs, freq=f, lower=lower, upper=upper, pol_order_high=pol_order_high,
                          frf_form=quantity)
        model.get_poles(method="lscf", show_progress=False)
        model.select_closest_poles(approx, f_window=f_window)
        lo = int(np.argmin(np.abs(model.freq - lower)))
        hi = model.freq.size
        rec, _ = model.get_constants(method="lsfd", f_lower=model.freq[lo], f_upper=model.freq[-1])
    seconds = time.perf_counter() - start
    fn = np.asarray(model.nat_freq, float)
    xi = np.asarray(model.nat_xi, float)
    missing = ~(fn > 0) | ~(xi > 0)  # select_closest_poles returns 0 where nothing was stable
    fn[missing], xi[missing] = np.nan, np.nan
    data = model.frf[:, lo:hi]
    error = float(np.sqrt(np.mean(np.abs(rec[:, lo:hi] - data) ** 2) / np.mean(np.abs(data) ** 2)))
    return {"frequency_hz": fn, "damping_ratio": xi, "reconstruction": error, "seconds": seconds,
            "lines": hi - lo, "f_window": f_window}


# --------------------------------------------------------------------------------------------
# synthetic

def synthetic(name: str, case: dict, seeds: int) -> dict:
    fr, zr = np.asarray(case["natural_hz"]), np.asarray(case["damping"])
    f = np.arange(0.0, F_MAX + RESOLUTION_HZ / 2, RESOLUTION_HZ)
    constants = SHAPES[:, :fr.size] * (100.0 * zr)
    clean = modal_superposition(f, fr, zr, constants, "accelerance")
    keep = f > 0  # no line at 0 Hz (accelerance to mobility)
    f, clean = f[keep], clean[:, keep]
    err = {tool: {q: np.full((seeds, fr.size), np.nan) for q in ("f", "z")} for tool in ("cf", "lscf")}
    times = {"cf": [], "lscf": []}
    flags, recon, found = [], [], []
    for seed in range(seeds):
        noisy = add_noise(clean, SNR_DB, np.random.default_rng(seed))
        bands, estimates, t_cf = circle(f, noisy, "accelerance", case.get("bands"))
        found.append(len(bands))
        approx = peak_frequencies(f, noisy, bands)
        peer = lscf(f, noisy, "accelerance", approx, **case["lscf"])
        times["cf"].append(t_cf)
        times["lscf"].append(peer["seconds"])
        recon.append(peer["reconstruction"])
        for est in estimates:
            r = int(np.argmin(np.abs(fr - est.frequency_hz)))  # the true mode this band found
            if abs(est.frequency_hz / fr[r] - 1) > 0.02:
                continue
            err["cf"]["f"][seed, r] = abs(est.frequency_hz / fr[r] - 1)
            err["cf"]["z"][seed, r] = abs(est.damping_ratio / zr[r] - 1)
            flags.append((r, est.flags))
        for fn, xi in zip(peer["frequency_hz"], peer["damping_ratio"]):  # each LSCF pick to its nearest true mode
            r = int(np.argmin(np.abs(fr - fn))) if np.isfinite(fn) else -1
            if r >= 0 and abs(fn / fr[r] - 1) < 0.02:
                err["lscf"]["f"][seed, r] = abs(fn / fr[r] - 1)
                err["lscf"]["z"][seed, r] = abs(xi / zr[r] - 1)

    print(f"\n=== Synthetic, {name}: {fr.size} modes, {SHAPES.shape[0]} sensors, accelerance 0-{F_MAX:g} Hz at "
          f"{RESOLUTION_HZ} Hz, {SNR_DB:g} dB SNR, {seeds} seeds; relative errors |est/truth - 1|, median [90th pct]")
    source = "user bands" if case.get("bands") else "bands found by find_mode_bands"
    print(f"    {source} per seed: {sorted(set(found))}; LSCF pol_order_high "
          f"{case['lscf']['pol_order_high']}, band {case['lscf']['lower']:g}-{case['lscf']['upper']:g} Hz")
    print(f"{'mode':>16} | {'circle fit: freq':>22} {'damping':>22} {'flagged':>7} | {'LSCF: freq':>22} "
          f"{'damping':>22} {'found':>5}")
    rows = []
    for r in range(fr.size):
        cells = []
        for tool in ("cf", "lscf"):
            for q in ("f", "z"):
                v = err[tool][q][:, r]
                v = v[np.isfinite(v)]
                cells.append(f"{np.median(v):9.2e} [{np.percentile(v, 90):9.2e}]" if v.size else f"{'none':>22}")
        flagged = [fl for rr, fl in flags if rr == r]
        n_flag = sum(1 for fl in flagged if fl)
        n_found = int(np.isfinite(err["lscf"]["f"][:, r]).sum())
        print(f"{fr[r]:7g} Hz {100 * zr[r]:4.1f} % | {cells[0]} {cells[1]} {n_flag:3d}/{len(flagged):<3d} | "
              f"{cells[2]} {cells[3]} {n_found:2d}/{seeds:<2d}")
        rows.append({k: np.nanmedian(err[t][q][:, r]) if np.isfinite(err[t][q][:, r]).any() else np.nan
                     for k, t, q in (("cf_f", "cf", "f"), ("cf_z", "cf", "z"), ("lscf_f", "lscf", "f"),
                                     ("lscf_z", "lscf", "z"))})
    common = sorted({fl for _, fls in flags for fl in fls})
    print(f"    circle-fit flags raised: {', '.join(common) if common else 'none'}; LSFD reconstruction error "
          f"(RMS, relative) median {np.median(recon):.2e}")
    print(f"    time per FRF set (median of {seeds}): circle fit {1e3 * np.median(times['cf']):.0f} ms, "
          f"LSCF+LSFD {1e3 * np.median(times['lscf']):.0f} ms")
    return {"rows": rows, "times": times, "truth": (fr, zr), "found": found, "seeds": seeds,
            "lscf_found": [int(np.isfinite(err["lscf"]["f"][:, r]).sum()) for r in range(fr.size)]}


# --------------------------------------------------------------------------------------------
# real data

def order_sweep(f, frfs, quantity, approx, lower, upper) -> list[np.ndarray]:
    """LSCF frequencies per order in ORDER_SWEEP (sensitivity of the pick to the model order)."""
    return [lscf(f, frfs, quantity, approx, lower=lower, upper=upper, pol_order_high=n)["frequency_hz"]
            for n in ORDER_SWEEP]


def unesp(root: Path) -> dict:
    campaign = import_unesp_bert(root / "unesp-bert-bolted-beam", FRAMES / "unesp_bert.toml")
    tests = campaign.test_ids
    sets = {t: frf_set(campaign, t) for t in tests}
    volts = [float(v) for v in campaign.design.set_index("test_id").loc[tests, "amplitude"]]
    start = time.perf_counter()
    bands, estimates = extract_tests({t: sets[t].frequency_hz for t in tests}, {t: sets[t].values for t in tests},
                                     campaign.quantity)
    t_cf = time.perf_counter() - start
    approx_all = peak_frequencies(sets[tests[0]].frequency_hz, np.concatenate([sets[t].values for t in tests]), bands)
    cf, peer = {}, {}
    for t in tests:
        s = sets[t]
        cf[t] = estimates[t]
        peer[t] = lscf(s.frequency_hz, s.values, campaign.quantity, peak_frequencies(s.frequency_hz, s.values, bands),
                       **UNESP_LSCF)
    print(f"\n=== UNESP-BERT, random 0-110 Hz, accelerometers acc1..acc4 over shaker voltage, {len(tests)} levels "
          f"({sets[tests[0]].values.shape[1]} lines {sets[tests[0]].frequency_hz[0]:g}-"
          f"{sets[tests[0]].frequency_hz[-1]:g} Hz)")
    print(f"    circle-fit bands (found once over all levels): "
          f"{', '.join(f'{lo:.2f}-{hi:.2f} Hz' for lo, hi in bands)}; LSCF pol_order_high "
          f"{UNESP_LSCF['pol_order_high']}, {UNESP_LSCF['lower']:g}-{UNESP_LSCF['upper']:g} Hz, f_window "
          f"{peer[tests[0]]['f_window']:g} Hz")
    head = " | ".join(f"mode {k + 1}: CF f Hz  z %  [95 % interval] | LSCF f Hz  z % inside" for k in range(len(bands)))
    print(f"{'level':>7} | {head} | flags (CF)")
    checks = []  # (level, mode, CF z, interval, LSCF z, relative disagreement, inside)
    for t, v in zip(tests, volts):
        cells = []
        for k in range(len(bands)):
            e, p = cf[t][k], peer[t]
            z_peer = p["damping_ratio"][k]
            inside = bool(e.damping_ci95[0] <= z_peer <= e.damping_ci95[1])
            checks.append((v, k + 1, e.damping_ratio, e.damping_ci95, z_peer, abs(e.damping_ratio / z_peer - 1), inside))
            cells.append(f"{e.frequency_hz:14.3f} {100 * e.damping_ratio:5.2f} [{100 * e.damping_ci95[0]:4.2f}-"
                         f"{100 * e.damping_ci95[1]:4.2f}] | {p['frequency_hz'][k]:9.3f} {100 * z_peer:5.2f} "
                         f"{'yes' if inside else 'NO':>6}")
        fl = "; ".join(",".join(e.flags) or "-" for e in cf[t])
        print(f"{v:5.2f} V | " + " | ".join(cells) + f" | {fl}")
    disagree = [c for c in checks if c[5] > 0.2]
    accepted = all(c[6] for c in disagree)
    print(f"    acceptance (LSCF damping inside the circle-fit interval wherever they disagree by more than 20 %): "
          f"{sum(c[6] for c in disagree)}/{len(disagree)} such modes ("
          + ", ".join(f"{c[0]:.2f} V mode {c[1]}: {100 * c[5]:.0f} %" for c in disagree)
          + f"): {'MET' if accepted else 'NOT MET'}; LSCF inside the interval for {sum(c[6] for c in checks)}/"
          f"{len(checks)} modes in all")
    rec = [peer[t]["reconstruction"] for t in tests]
    print(f"    LSFD reconstruction error (RMS, relative): {min(rec):.2f}-{max(rec):.2f}")
    print(f"    time for the six levels: circle fit (bands + fits + combine) {t_cf:.2f} s, "
          f"LSCF+LSFD {sum(peer[t]['seconds'] for t in tests):.2f} s")
    # trend of mode 2 with level
    k = len(bands) - 1
    trend, growth = {}, {}
    print(f"    trend of mode {k + 1} with the level (Spearman rank correlation over the {len(tests)} levels):")
    for tool, fk, zk in (("circle fit", [cf[t][k].frequency_hz for t in tests], [cf[t][k].damping_ratio for t in tests]),
                         ("LSCF", [peer[t]["frequency_hz"][k] for t in tests], [peer[t]["damping_ratio"][k] for t in tests])):
        rho_f, rho_z = spearmanr(volts, fk)[0], spearmanr(volts, zk)[0]
        softens, damps = fk[-1] < fk[0] and rho_f < 0, zk[-1] > zk[0] and rho_z > 0
        trend[tool] = softens and damps
        growth[tool] = zk[-1] - zk[0]
        print(f"      {tool:10}: {fk[0]:.3f} -> {fk[-1]:.3f} Hz ({fk[-1] - fk[0]:+.3f} Hz, rho {rho_f:+.2f}), "
              f"damping {100 * zk[0]:.2f} -> {100 * zk[-1]:.2f} % (rho {rho_z:+.2f}): "
              f"{'softens and damping grows' if trend[tool] else 'trend NOT seen'}")
    # sensitivity of the LSCF pick to the order, lowest and highest level
    for t in (tests[0], tests[-1]):
        s = sets[t]
        sweep = np.array(order_sweep(s.frequency_hz, s.values, campaign.quantity,
                                     peak_frequencies(s.frequency_hz, s.values, bands), UNESP_LSCF["lower"],
                                     UNESP_LSCF["upper"]))
        print(f"    LSCF sensitivity to pol_order_high {ORDER_SWEEP} at {t}: " + "; ".join(
            f"mode {m + 1} {np.nanmin(sweep[:, m]):.3f}-{np.nanmax(sweep[:, m]):.3f} Hz" for m in range(sweep.shape[1])))
    diffs_f = [abs(cf[t][m].frequency_hz - peer[t]["frequency_hz"][m]) for t in tests for m in range(len(bands))]
    diffs_z = {m: [100 * (cf[t][m].damping_ratio - peer[t]["damping_ratio"][m]) for t in tests] for m in range(len(bands))}
    # mode 1 across the window change (uniform up to 0.20 V, Hanning at 0.25 and 0.30 V)
    step = {"circle fit": np.mean([cf[t][0].damping_ratio for t in tests[4:]]) - np.mean([cf[t][0].damping_ratio for t in tests[:4]]),
            "LSCF": np.mean([peer[t]["damping_ratio"][0] for t in tests[4:]]) - np.mean([peer[t]["damping_ratio"][0] for t in tests[:4]])}
    return {"trend": trend, "growth": growth, "step": step, "max_df": max(diffs_f), "dz": diffs_z, "approx": approx_all,
            "checks": checks, "accepted": accepted, "flagged": sum(bool(e.flags) for t in tests for e in cf[t])}


def quadrature(f: np.ndarray, h: np.ndarray) -> float:
    """Phase resonance of a stepped-sine FRF: where the unwrapped phase passes half-way between
    its values at the band edges (90 deg of the 180 deg swing), linearly interpolated."""
    phase = np.unwrap(np.angle(h))
    middle = 0.5 * (phase[0] + phase[-1])
    k = np.nonzero(np.diff(np.sign(phase - middle)))[0]
    if not k.size:
        return float("nan")
    i = int(k[0])
    return float(f[i] + (f[i + 1] - f[i]) * (middle - phase[i]) / (phase[i + 1] - phase[i]))


def brake_reuss(root: Path) -> dict:
    campaign = import_brake_reuss(root / "rice-brb-brake-reuss-beam", FRAMES / "brake_reuss.toml", control="force")
    tests = campaign.test_ids
    levels = campaign.design.set_index("test_id").loc[tests, "amplitude"].tolist()
    print(f"\n=== Brake-Reuss beam, force-controlled stepped sine, drive-point accelerance, {len(tests)} levels; "
          f"circle fit on all 41 lines, LSCF pol_order_high {BRB_LSCF['pol_order_high']}")
    print(f"{'force':>7} | {'|H| peak Hz':>11} {'quadrature':>10} | {'CF f Hz':>8} {'z %':>5} {'[95 % interval]':>15} "
          f"{'circle err':>10} | {'LSCF f Hz':>9} {'z %':>5} {'inside':>6} {'LSFD err':>8} | "
          f"{'LSCF f over orders ' + str(ORDER_SWEEP):>34} | flags (CF)")
    out = []
    t_cf = t_peer = 0.0
    for t, level in zip(tests, levels):
        s = frf_set(campaign, t)
        f, h = s.frequency_hz, s.values
        peak = float(f[np.argmax(np.abs(h[0]))])
        _, (e,), seconds = circle(f, h, campaign.quantity, bands=[(f[0], f[-1])])
        t_cf += seconds
        p = lscf(f, h, campaign.quantity, [peak], lower=f[0], upper=f[-1], **BRB_LSCF)
        t_peer += p["seconds"]
        sweep = np.array(order_sweep(f, h, campaign.quantity, [peak], f[0], f[-1]))[:, 0]
        found = np.isfinite(sweep)
        span = (f"{np.nanmin(sweep):.3f}-{np.nanmax(sweep):.3f} Hz, found at {found.sum()}/{found.size}"
                if found.any() else "no stable pole at any order")
        inside = bool(e.damping_ci95[0] <= p["damping_ratio"][0] <= e.damping_ci95[1])
        print(f"{level:>5} N | {peak:11.2f} {quadrature(f, h[0]):10.3f} | {e.frequency_hz:8.3f} {100 * e.damping_ratio:5.2f} "
              f"[{100 * e.damping_ci95[0]:5.3f}-{100 * e.damping_ci95[1]:5.3f}] {e.fits[0].circle_error:10.3f} | "
              f"{p['frequency_hz'][0]:9.3f} {100 * p['damping_ratio'][0]:5.2f} {'yes' if inside else 'NO':>6} "
              f"{p['reconstruction']:8.3f} | {span:>34} | {','.join(e.flags) or '-'}")
        out.append((float(level), peak, e.frequency_hz, e.damping_ratio, p["frequency_hz"][0], p["damping_ratio"][0],
                    p["reconstruction"], e.fits[0].circle_error))
    print(f"    time for the four levels: circle fit {1e3 * t_cf:.0f} ms, LSCF+LSFD {1e3 * t_peer:.0f} ms")
    z_cf, z_peer = [o[3] for o in out], [o[5] for o in out]
    print(f"    damping vs force (Spearman): circle fit rho {spearmanr(levels, z_cf)[0]:+.2f}, "
          f"LSCF rho {spearmanr(levels, z_peer)[0]:+.2f}")
    return {"rows": out}


# --------------------------------------------------------------------------------------------

def verdict(results: dict, real: dict) -> None:
    """Numbers first, then the reading (the explanations are this benchmark's, stated as such)."""
    print("\n=== Verdict")
    sep = results["well separated"]
    rows = sep["rows"]
    inside = all(r["cf_f"] < 1e-4 and r["cf_z"] < 0.05 and r["lscf_f"] < 1e-4 and r["lscf_z"] < 0.05 for r in rows)
    print("  MATCHES on well-separated modes (synthetic, 40 dB): median errors circle fit / LSCF, frequency "
          + ", ".join(f"{fr:g} Hz {r['cf_f']:.0e}/{r['lscf_f']:.0e}" for fr, r in zip(sep["truth"][0], rows))
          + "; damping " + ", ".join(f"{r['cf_z']:.0e}/{r['lscf_z']:.0e}" for r in rows)
          + f": {'both well inside' if inside else 'NOT both inside'} the targets (1e-4, 5 %). LSCF+LSFD is faster "
          f"({1e3 * np.median(sep['times']['lscf']):.0f} vs {1e3 * np.median(sep['times']['cf']):.0f} ms per set: one "
          "polynomial for all sensors and modes, against a nonlinear least-squares circle per curve and mode).")
    auto, user = results["close pair, automatic bands"], results["close pair, user bands"]
    rows = auto["rows"]
    print(f"  CLOSE PAIR, 240/250 Hz at 1 % (2 half-power bandwidths apart, one peak to find_mode_bands): the "
          f"automatic bands now give {sorted(set(auto['found']))} mode(s) per draw (split_bands: a two-pole fit over "
          "the four sensors accepted, the band listed twice and fitted with two common poles), frequency errors "
          + ", ".join(f"{r['cf_f']:.0e}" for r in rows) + ", damping " + ", ".join(f"{r['cf_z']:.0e}" for r in rows)
          + f" (median), flagged close_mode; LSCF, started from the single peak, returns the 250 Hz pole in "
          f"{auto['lscf_found'][-1]}/{auto['seeds']} draws and the 240 Hz one in {auto['lscf_found'][0]}. With the "
          "user's bands split halfway both tools find both (circle fit " + ", ".join(f"{r['cf_f']:.0e}" for r in user["rows"])
          + "; LSCF " + ", ".join(f"{r['lscf_f']:.0e}" for r in user["rows"]) + ").")
    if "unesp" in real:
        u = real["unesp"]
        print(f"  UNESP-BERT: frequencies agree within {u['max_df']:.3f} Hz at every level and mode. Damping, circle fit "
              "minus LSCF (points of %): " + "; ".join(f"mode {m + 1} {min(v):+.2f}..{max(v):+.2f}" for m, v in u["dz"].items())
              + ". Mode 2 softens and its damping grows with the level for both tools "
              f"(circle fit {'yes' if u['trend']['circle fit'] else 'NO'}, LSCF {'yes' if u['trend']['LSCF'] else 'NO'}), "
              f"damping growth {100 * u['growth']['circle fit']:+.2f} (circle fit) and {100 * u['growth']['LSCF']:+.2f} "
              "(LSCF) points of %. Mode-1 damping is not resolved by either: its half-power "
              "band is about 3 lines (0.0625 Hz lines, about 0.19 Hz wide), and the window changes from uniform "
              "(0.05-0.20 V) to Hanning (0.25-0.30 V): mean damping step there "
              f"{100 * u['step']['circle fit']:+.2f} (circle fit) and {100 * u['step']['LSCF']:+.2f} (LSCF) points of %. "
              f"{u['flagged']} of the {len(u['checks'])} circle-fit modes are flagged: the misfits are systematic (the "
              "level-dependent joint, leakage), but the two-pole fit's \"second pole\" has the first's shape, so no "
              "close_mode; the damping interval then allows the half-power bandwidth +-2 lines (LEAKAGE_LINES), wide "
              "for mode 1 (3 lines in its half-power band). Acceptance, LSCF damping inside the circle-fit interval "
              "wherever the two disagree by more than 20 %: " + ("MET" if u["accepted"] else "NOT MET") + " ("
              + ", ".join(f"{c[0]:.2f} V mode {c[1]} LSCF {100 * c[4]:.2f} % in [{100 * c[3][0]:.2f}, {100 * c[3][1]:.2f}]"
                          for c in u["checks"] if c[5] > 0.2) + ").")
    if "brb" in real:
        rows = real["brb"]["rows"]
        print("  Brake-Reuss (41 stepped-sine lines): LSCF does work on them (a stable pole at every order tried) but "
              f"its LSFD model misses the data by {100 * min(o[6] for o in rows):.0f}-{100 * max(o[6] for o in rows):.0f} % RMS "
              f"(circle errors {100 * min(o[7] for o in rows):.1f}-{100 * max(o[7] for o in rows):.1f} %). Frequency circle fit minus LSCF "
              + ", ".join(f"{o[2] - o[4]:+.3f}" for o in rows) + " Hz, circle fit minus |H| peak "
              + ", ".join(f"{o[2] - o[1]:+.3f}" for o in rows) + " Hz: they match at the two lowest forces; at the "
              "two highest the circle-fit frequency moves above the peak and the phase resonance, because the "
              "stepped-sine FRF of a softening friction joint is not a linear one-mode FRF: its points still lie on "
              "a near circle (small circle error) but they sweep it fastest above the phase resonance. Damping "
              "(circle fit vs LSCF) " + ", ".join(f"{100 * o[3]:.2f}/{100 * o[5]:.2f}" for o in rows)
              + " %: both grow with the force; the circle fit reads more damping at the high forces; at 0.2 N the "
              "half-power band holds about 4 lines, so neither damping is well resolved.")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--real-root", type=Path, default=REAL_ROOT)
    args = parser.parse_args()

    print(f"workbench {version('workbench')}, sdypy-EMA {version('sdypy-EMA')}, numpy {np.__version__}; "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}")
    results = {name: synthetic(name, case, args.seeds) for name, case in SYNTHETIC.items()}
    real = {}
    if (args.real_root / "unesp-bert-bolted-beam").is_dir():
        real["unesp"] = unesp(args.real_root)
    else:
        print(f"\n(UNESP-BERT skipped: {args.real_root / 'unesp-bert-bolted-beam'} absent)")
    if (args.real_root / "rice-brb-brake-reuss-beam").is_dir():
        real["brb"] = brake_reuss(args.real_root)
    else:
        print(f"\n(Brake-Reuss skipped: {args.real_root / 'rice-brb-brake-reuss-beam'} absent)")

    verdict(results, real)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
