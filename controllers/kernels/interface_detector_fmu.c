/* The InterfaceDetector's C step as it runs inside its exported FMU (issue #21):
 * kernels/interface_detector.c built self-contained -- its own dot product for the
 * regression's prediction, the localisation fit of event_locator.py ported to C
 * (kernels/event_locator.c) -- on a state that holds its own arrays.
 *
 * The in-process block keeps its BLAS ddot and its Python fit (bit-identical to the Python
 * step). This build sums the prediction in the order of the BLAS kernel numpy uses on AVX2
 * machines (detector_dot) and fits as the Python does, its solves done otherwise: measured,
 * the same doubles as the in-process step on this project's machines (docs/export.md).
 *
 * State: the Detector, then the constants only this build needs, then its arrays, laid
 * out one after the other (their sizes follow from N and N_min), so that the FMU's state
 * is one block of memory it can copy (get/set FMU state) and the pointers are set from
 * it at every step. Mirrored by controllers/detector_kernel.py:export_state_type.
 */
#define DETECTOR_SELF_CONTAINED 1
#define DET_ENTRY_BACK 1.0   /* interface_detector.ENTRY_BACK: margins before the entry candidate the fit reaches */
#define DET_AIR_RING_ORBITS 2.0   /* interface_detector.AIR_RING_ORBITS */
#define DET_ENTRY_RAMP_SLACK 1.5  /* interface_detector.ENTRY_RAMP_SLACK */
#define DET_PI 3.141592653589793  /* math.pi */
#define DET_EXIT_HEAD_SHARE 0.8   /* interface_detector.EXIT_HEAD_SHARE */
#define DET_MAX_RIPPLE 4          /* air_ripple.MAX_PITCHES */
#define DET_RIPPLE_SPEED_SAMPLES 50     /* air_ripple.SPEED_SAMPLES */
#define DET_RIPPLE_SPEED_SHARE 0.1      /* air_ripple.SPEED_SHARE */
#define DET_RIPPLE_SPAN_S 8.0           /* air_ripple.SPAN_S */
#define DET_RIPPLE_MIN_SAMPLES 100      /* air_ripple.MIN_SAMPLES */
#include "event_locator.c"
#include "interface_detector.c"

typedef struct {
    Detector d;
    double observer_delay;                        /* s, the observer's lag (the fit's positions) */
    double exit_period;                           /* samples, the last layer's orbit (the exit's fit) */
    double entry_period;                          /* samples, the first layer's orbit (the entry's fit; 0: none) */
    double entry_shape;                           /* the entry's ramp: 0 any, 1 linear, 2 smoothstep (event_locator.ENTRY_SHAPES) */
    double exit_ghost[2];                         /* the exit's fit: orbit [samples] (0: none), decay per sample */
    double exit_shape;                            /* the exit's push-out law: 0 any, 1 linear, 2 quadratic, 3 bending
                                                     (event_locator.EXIT_SHAPES) */
    double exit_compliance;                       /* m/N, encoder to cutting front (InterfaceDetector._front_positions) */
    double rise_ramp;                             /* 1: an interface's rise takes the plan's ramp (InterfaceDetector._plan_ramp_at_rises) */
    double entry_engagement;                      /* m, the plan's engagement at the entry (0: none; InterfaceDetector._entry_ramp_max) */
    double observer_lag;                          /* s, the observer's lag behind a ramp (InterfaceDetector._exit_time) */
    double observer_step_lag;                     /* s, its lag behind a step (InterfaceDetector._interface_time) */
    double exit_release[3];                       /* the exit's released push-out: compliance [m/N] (0: off), x_feed
                                                     (InterfaceDetector._exit_release), its share up to the tool
                                                     tip [m/N] (InterfaceDetector._exit_time) */
    double process;                               /* 1: the plan gives each layer's process (InterfaceDetector.process),
                                                     0: none (an interface's drop fits free laws) */
    double layer_feed_rate[DET_MAX_LAYERS];       /* m/s, the feed rate commanded in each layer */
    double layer_feed_per_rev[DET_MAX_LAYERS];    /* m/rev, each layer's feed per revolution */
    double process_ramp;                          /* s, the adaptation's raised cosine from each trigger (0: a step) */
    double n_ripple;                              /* the drive ripple's pitches in use (InterfaceDetector.air_ripple_pitches) */
    double ripple_pitches[DET_MAX_RIPPLE];        /* m, each one's travel along the table */
    double engage_lengths[LOC_N_ENGAGE];          /* m, event_locator.ENGAGE_LENGTHS */
    double engage_fine[LOC_N_FINE];               /* around the best engage length */
    double push_out_lengths[LOC_N_PUSH_OUT];      /* m, event_locator.PUSH_OUT_LENGTHS */
    double push_out_fine[LOC_N_FINE];
    /* weights of the windows N_min..N, window (N), |F~| ring (2 N), history t, x, F */
    double data[];
} DetectorFMU;

/* The prediction W . buf in the summation order of OpenBLAS's Haswell/Zen ddot kernel, the
 * one numpy calls on an AVX2 machine: over the first n & -16 terms four accumulators of four
 * lanes, each term fused (fma); each accumulator's high pair added onto its low pair, the
 * four pairs added (0 + 1) + (2 + 3), the two lanes added; then the rest left to right.
 * Written in portable C (fma() is exact everywhere), so the FMU gives the same doubles on
 * any platform, and those of the in-process step where numpy uses that kernel
 * (detector_kernel.export_dot_is_numpys says whether it does here). */
static double detector_dot(long n, const double *w, const double *buf)
{
    double acc[4][4] = {{0.0}}, dot = 0.0;
    long n16 = n & -16, i;
    for (i = 0; i < n16; i += 16)
        for (int a = 0; a < 4; a++)
            for (int l = 0; l < 4; l++)
                acc[a][l] = fma(w[i + 4 * a + l], buf[i + 4 * a + l], acc[a][l]);
    if (n16 > 0) {
        double pair[4][2];
        for (int a = 0; a < 4; a++)
            for (int l = 0; l < 2; l++)
                pair[a][l] = acc[a][l] + acc[a][l + 2];
        double lo = (pair[0][0] + pair[1][0]) + (pair[2][0] + pair[3][0]);
        double hi = (pair[0][1] + pair[1][1]) + (pair[2][1] + pair[3][1]);
        dot = lo + hi;
    }
    for (; i < n; i++)
        dot += buf[i] * w[i];
    return dot;
}

/* for the check that this dot is numpy's here */
double interface_detector_fmu_dot(long n, const double *w, const double *buf)
{
    return detector_dot(n, w, buf);
}

/* numpy.interp(q, xp, fp) at one point, xp increasing */
static double detector_interp(double q, const double *xp, const double *fp, long n)
{
    if (isnan(q))
        return q;
    if (q < xp[0])
        return fp[0];
    if (q > xp[n - 1])
        return fp[n - 1];
    long lo = 0, hi = n - 1;            /* xp[lo] <= q <= xp[hi] */
    while (hi - lo > 1) {
        long mid = (lo + hi) / 2;
        if (xp[mid] <= q)
            lo = mid;
        else
            hi = mid;
    }
    if (q == xp[n - 1])
        return fp[n - 1];
    if (xp[lo] == q)
        return fp[lo];
    double slope = (fp[lo + 1] - fp[lo]) / (xp[lo + 1] - xp[lo]);
    double v = slope * (q - xp[lo]) + fp[lo];
    if (isnan(v)) {
        v = slope * (q - xp[lo + 1]) + fp[lo + 1];
        if (isnan(v) && fp[lo] == fp[lo + 1])
            v = fp[lo];
    }
    return v;
}

/* event_locator.time_at: first time [s] the position reached x_loc, interpolated */
static double detector_time_at(const double *t, const double *x, long n, double x_loc)
{
    if (!isfinite(x_loc))
        return NAN;
    for (long i = 0; i < n; i++) {
        if (!(x[i] >= x_loc))
            continue;
        if (i == 0 || x[i] == x[i - 1])
            return t[i];
        return t[i - 1] + (t[i] - t[i - 1]) * (x_loc - x[i - 1]) / (x[i] - x[i - 1]);
    }
    return NAN;
}

/* the fit's samples: the history oldest first (t, x, F), each force sample against where
 * the tool was when the observer saw it (xs) */
static long detector_history(const DetectorFMU *s, double h_n, double *t, double *x, double *F, double *xs)
{
    long written = (long)h_n, n = written < DET_HISTORY ? written : DET_HISTORY;
    for (long j = 0; j < n; j++) {
        long i = (written - n + j) % DET_HISTORY;
        t[j] = s->d.h_t[i];
        x[j] = s->d.h_x[i];
        F[j] = s->d.h_F[i];
    }
    for (long j = 0; j < n; j++)
        xs[j] = s->observer_delay > 0.0 ? detector_interp(t[j] - s->observer_delay, t, x, n) : x[j];
    return n;
}

/* interface_detector.air_level: F[0..a) the air samples (overwritten), period [samples] the
 * first layer's orbit (<= 0: none) -> out[0] the air level [N], out[1] its spread [N] */
static void detector_air_level(double *F, long a, double period, double *out)
{
    out[0] = loc_mean(F, a);
    double *dev = F + a;      /* scratch after the samples: the caller's history holds room */
    for (long j = 0; j < a; j++)       /* the rms deviation, as numpy's mean of the squares */
        dev[j] = (F[j] - out[0]) * (F[j] - out[0]);
    double sd = sqrt(loc_mean(dev, a));
    out[1] = sd;
    if (!(period > 0.0) || a < 2 || (double)a >= DET_AIR_RING_ORBITS * period)
        return;
    for (long j = 0; j + 1 < a; j++)   /* numpy.diff, squared */
        dev[j] = (F[j + 1] - F[j]) * (F[j + 1] - F[j]);
    double noise = sqrt(loc_mean(dev, a - 1) / 2.0);
    double ring = sqrt(2.0 * LOC_PYMAX(sd * sd - noise * noise, 0.0)) * LOC_PYMIN(1.0, period / (DET_PI * (double)a));
    out[1] = LOC_PYMIN(sd, noise + ring);
}

/* InterfaceDetector._interface_ghost: interface k's {lower layer's orbit [samples], the exit's
 * decay} in ghost, or NULL (no exit ghost, no orbit, a push-out law other than linear: code 1) */
static const double *interface_ghost(const DetectorFMU *s, int k, double *ghost)
{
    if (!(s->exit_ghost[0] > 0.0 && s->exit_ghost[1] > 0.0) || s->exit_shape != 1.0)
        return NULL;
    ghost[0] = k < (int)s->d.n - 1 ? s->d.if_P[k] : s->exit_ghost[0];
    ghost[1] = s->exit_ghost[1];
    return ghost[0] > 0.0 ? ghost : NULL;
}

/* InterfaceDetector._blend: the adaptation's raised-cosine blend (0 -> 1) at time t [s] from the
 * trigger at t_ev [s] over ramp [s] (libm's cos, as the Python's math.cos) */
static double detector_blend(double t, double t_ev, double ramp)
{
    double v = ramp > 0.0 ? loc_clip01((t - t_ev) / ramp) : t >= t_ev ? 1.0 : 0.0;
    return 0.5 * (1.0 - cos(DET_PI * v));
}

/* InterfaceDetector._process_change: the adaptation's process change at interface k's trigger
 * -- the share (f(t) / f_{k-1})^x_feed of the feed per revolution commanded at the force samples'
 * times t[0..m) [s], feed rate and spindle speed each blended by the raised cosine (cos, pow:
 * libm's, as the Python's math.cos and numpy's power; the exit's law, the drive's compliance) -- into share and
 * *fall; NULL where the plan gives no process or the hole has failed (the fail-safe's set is in
 * force) or the trigger has no time */
static const LocGrid *detector_process_change(const DetectorFMU *s, int k, const double *t, long m, const LocGrid *push,
                                              double *share, LocGrid *fall)
{
    double t_ev = s->d.t_ev[k];
    if (s->process == 0.0 || s->d.fail != 0.0 || !isfinite(t_ev))
        return NULL;
    double fa = s->layer_feed_rate[k - 1], fb = s->layer_feed_rate[k], f_up = s->layer_feed_per_rev[k - 1];
    double na = fa / f_up, nb = fb / s->layer_feed_per_rev[k], ramp = s->process_ramp, x_feed = s->exit_release[1];
    for (long j = 0; j < m; j++) {
        double r = detector_blend(t[j], t_ev, ramp);
        double q = (fa + r * (fb - fa)) / (na + r * (nb - na)) / f_up;
        share[j] = x_feed == 0.5 ? sqrt(q) : pow(q, x_feed);    /* numpy's ** 0.5 is its sqrt (pow: a last bit apart) */
    }
    *fall = loc_exit_grid(push, (int)s->exit_shape);
    fall->release[0] = s->exit_compliance + s->exit_release[0];
    fall->release[1] = x_feed;
    fall->share = share;
    return fall;
}

/* InterfaceDetector._air_shift: the air level's step at interface k's change of feed (the lower
 * feed's measured level less the upper's, where it stands out of their spreads), taken out of the window's thrust F[0..m) at the times
 * t [s] along the adaptation's raised cosine from the trigger; returns the step (0: none) */
static double detector_air_shift(const DetectorFMU *s, int k, const double *t, long m, double *F)
{
    double t_ev = s->d.t_ev[k], delta = s->d.air_F[k] - s->d.air_F[k - 1], ramp = s->process_ramp;
    if (s->process == 0.0 || s->d.fail != 0.0 || !isfinite(t_ev)
            || !(isfinite(delta) && fabs(delta) > DET_AIR_OFFSET_K * MAX(s->d.air_S[k], s->d.air_S[k - 1])))
        return 0.0;     /* a step within AIR_OFFSET_K of the levels' spreads is none (_air_shift) */
    for (long j = 0; j < m; j++)
        F[j] = F[j] - delta * detector_blend(t[j], t_ev, ramp);
    return delta;
}

/* InterfaceDetector._fit: out = x_loc [m], t_loc [s], dx [m], F_air [N], F_air_sd [N] */
/* the samples (x, F, t) with x <= end [m], moved to the front in their order; returns their count */
static long detector_keep_upto(double end, double *x, double *F, double *t, long m)
{
    long kept = 0;
    for (long i = 0; i < m; i++)
        if (x[i] <= end) {
            x[kept] = x[i];
            F[kept] = F[i];
            t[kept++] = t[i];
        }
    return kept;
}

/* InterfaceDetector._entry_fit_once: the entry's first fit out[0] (x_loc [m]), out[2] (dx [m])
 * refitted where the drive settles after the rise (_entry_refit), else with the cut's orbital ripple */
static void detector_entry_once(const Detector *d, const double *xsel, const double *Fsel, long m, double hi,
                                double x_trig, double air, double period, LocGrid *engage, const LocGrid *push,
                                double *scratch, double *out)
{
    double orbit = period > 0.0 && m > 1 ? period * (xsel[m - 1] - xsel[0]) / (double)(m - 1) : 0.0;
    double ramp = isfinite(out[0]) ? event_onset_length(xsel, Fsel, m, out[0], period, engage) : NAN;
    double reach = LOC_PYMAX(d->locate_margin, orbit + ramp), span = orbit > 0.0 ? orbit : 0.5 * d->locate_margin;
    if (isfinite(out[0]) && out[0] + reach < hi &&
        event_settling_fall(xsel, Fsel, m, out[0], ramp, span) > LOC_ENTRY_SETTLING) {
        /* _entry_refit: where the level falls after the rise (the drive settling), again on the
         * samples whose front is up to a reach past the onset: locate_margin, or the first fit's
         * ramp and an orbit of level (copied: the caller's window is cut again after) */
        double x2, dx2, *xk = scratch, *Fk = scratch + DET_HISTORY;
        long m2 = 0;
        for (long i = 0; i < m; i++)
            if (xsel[i] <= out[0] + reach) {
                xk[m2] = xsel[i];
                Fk[m2++] = Fsel[i];
            }
        event_locate(LOC_ENTRY, xk, Fk, m2, air, x_trig, NAN, period, NULL, engage, push, NULL, &x2, &dx2);
        if (isfinite(x2)) {
            out[0] = x2;
            out[2] = dx2;
        }
    } else if (isfinite(out[0]) && period > 0.0 && d->entry_ripple != 0.0) {
        /* _entry_fit_once: where the drive does not settle, again with the cut's orbital ripple on the ramp */
        double x2, dx2;
        const DetectorFMU *s = (const DetectorFMU *)d;    /* its ripple as the observer's ghost: the exit's decay */
        engage->cut_ripple = 1;
        event_locate(LOC_ENTRY, xsel, Fsel, m, air, x_trig, NAN, period, s->exit_ghost[0] > 0.0 ? s->exit_ghost : NULL,
                     engage, push, NULL, &x2, &dx2);
        engage->cut_ripple = 0;
        if (isfinite(x2)) {
            out[0] = x2;
            out[2] = dx2;
        }
    }
}

/* InterfaceDetector._layer_end: whether the entry's window (xsel, Fsel: m samples) is fitted again
 * up to level_reach[0] past its onset x_loc [m]: it reaches further, keeps 2 N_min samples past
 * the onset, and its last orbit mean has fallen below LOC_ENTRY_LAYER_FALL of its highest */
static int detector_layer_end(const Detector *d, const double *xsel, const double *Fsel, long m, double x_loc,
                              double air, double period)
{
    if (!isfinite(x_loc))
        return 0;
    double end = x_loc + d->level_reach[0];
    long kept = 0, past = 0;
    for (long i = 0; i < m; i++)
        if (xsel[i] <= end) {
            kept++;
            past += xsel[i] > x_loc;
        }
    return kept < m && past >= 2 * (long)d->N_min
           && !isnan(event_orbit_fell(xsel, Fsel, m, air, period, LOC_ENTRY_LAYER_FALL));
}

/* interface_detector.without_gap_head: the window (m samples) less its head where that lies in a
 * gap (the median of its first 2 MIN_SEGMENT samples below the layer's floor), up to its first
 * run of 2 MIN_SEGMENT samples at or above the floor, and at most its first upto samples (< 0:
 * no bound); the samples left */
static long detector_gap_head(double *xsel, double *Fsel, double *tsel, long m, double floor, long upto,
                              double *scratch)
{
    long seg = 2 * LOC_MIN_SEGMENT, head = m, run = 0;
    if (m < 2 * seg || !(loc_median(Fsel, seg, scratch) < floor))
        return m;
    for (long i = 0; i < m; i++) {
        run = Fsel[i] >= floor ? run + 1 : 0;
        if (run == seg) {
            head = i - seg + 1;
            break;
        }
    }
    if (upto >= 0 && upto < head)
        head = upto;
    if (head == 0 || head >= m)
        return m;
    memmove(xsel, xsel + head, (size_t)(m - head) * sizeof(double));
    memmove(Fsel, Fsel + head, (size_t)(m - head) * sizeof(double));
    memmove(tsel, tsel + head, (size_t)(m - head) * sizeof(double));
    return m - head;
}

/* InterfaceDetector._window_cut_floor: the level [N] below which interface k's shortened window is in a
 * gap: over the air level, both layers' floor or, where higher, the least level the upper layer's
 * observed one leaves the lower (the plan's ratio over mismatch_factor), at most AIR_SHARE of the upper's */
static double detector_window_cut_floor(const Detector *d, int k)
{
    double floor = LOC_PYMIN(d->floor[k - 1], d->floor[k]), upper = above_air(d, d->levels[k - 1]);
    if (d->mismatch_factor > 0.0 && upper > 0.0) {
        double least = upper * d->level_plan[k] / d->level_plan[k - 1] / d->mismatch_factor;
        floor = LOC_PYMAX(floor, LOC_PYMIN(LOC_AIR_SHARE * upper, least));
    }
    return air_offset(d) + floor;
}

/* InterfaceDetector._gap_air: out[0] the air level [N] and out[1] its spread in the gap interface k's
 * window (x, F at the observer's times t: m samples) crosses (its air run, or its run below cut_floor
 * [N], NaN: none) where the fit located the interface (x_loc [m]) in it, its faces' feet left out, on the
 * samples at layer k's feed (past the trigger and the adaptation's ramp); unchanged without
 * 2 LOC_MIN_SEGMENT of them, where they ring (rms beyond DET_AIR_GAP_QUIET times their noise) or
 * once the hole has failed */
static void detector_gap_air(const DetectorFMU *s, int k, const double *x, const double *F, const double *t, long m,
                             double air, double cut_floor, double x_loc, double *scratch, double *out)
{
    long i0, i1, a = 0;
    if (s->d.fail != 0.0 || !(loc_air_run(x, F, m, air, scratch, &i0, &i1)
                              || loc_floor_gap(F, m, cut_floor, scratch, &i0, &i1))
        || !(x[i0] <= x_loc && x_loc <= x[i1 - 1]))     /* located outside the run: no gap (a ringing trough) */
        return;
    long q = (long)(LOC_RUN_FEET * (double)(i1 - i0));
    for (long i = i0 + q; i < i1 - q; i++)
        if (s->process == 0.0 || t[i] >= s->d.t_ev[k] + s->process_ramp)
            scratch[a++] = F[i];
    if (a < 2 * LOC_MIN_SEGMENT)
        return;
    double level[2], *dev = scratch + a;
    detector_air_level(scratch, a, 0.0, level);
    for (long j = 0; j + 1 < a; j++)   /* numpy.diff, squared: the samples' noise */
        dev[j] = (scratch[j + 1] - scratch[j]) * (scratch[j + 1] - scratch[j]);
    if (level[1] <= DET_AIR_GAP_QUIET * sqrt(loc_mean(dev, a - 1) / 2.0)) {
        out[0] = level[0];
        out[1] = level[1];
    }
}

/* InterfaceDetector._exit_time: the time [s] the tool tip reached the exit's face x_loc [m]: the fit's
 * positions (x at times t: m samples) less the deflection the frame still stored (the release's share up to
 * the tool tip times F over air) first reach it, less the observer's lag beyond observer_delay; NaN where
 * they never do */
static double detector_exit_time(const DetectorFMU *s, const double *t, const double *x, const double *F, long m,
                                 double air, double x_loc, double *tool)
{
    for (long i = 0; i < m; i++)
        tool[i] = x[i] - s->exit_release[2] * LOC_PYMAX(F[i] - air, 0.0);
    return detector_time_at(t, tool, m, x_loc) - LOC_PYMAX(s->observer_lag - s->observer_delay, 0.0);
}

/* InterfaceDetector._interface_time: an interface's located time [s] where its upper layer broke off
 * (loc_break_off on the fit's samples: x, F at the observer's times t, m of them) and the tool's
 * snap reached the located position x_loc: the encoder reached it (at t_enc, the observer's times)
 * before the thrust reached the gap, or it lies within the tool's share of the released deflection
 * past the encoder there; then when the thrust fell half-way, less the observer's step lag beyond
 * observer_delay; else NaN */
static double detector_interface_time(const DetectorFMU *s, const double *t, const double *x, const double *F,
                                      long m, double air, double t_enc, double x_loc)
{
    double fall[4];
    if (!(s->exit_release[0] > 0.0) || !loc_break_off(t, x, F, m, air, s->exit_release[0], fall)
        || !(t_enc <= fall[1] || x_loc <= fall[2] + s->exit_release[2] * fall[3]))
        return NAN;
    return fall[0] - LOC_PYMAX(s->observer_step_lag - s->observer_delay, 0.0);
}

/* air_ripple.approach_samples: the approach's samples [*start, first) before the window's first sample at the
 * speed it had just before it (t, x: the history's times and positions); 0 where too few or too short */
static int detector_approach(const double *t, const double *x, long first, double travel, long *start)
{
    const long B = DET_RIPPLE_SPEED_SAMPLES;
    long last = first - 1;
    if (last - B < 0 || !(t[last] > t[last - B]))
        return 0;
    double v_ref = (x[last] - x[last - B]) / (t[last] - t[last - B]);
    if (!(v_ref > 0.0))
        return 0;
    long a = last;
    while (a - 1 - B >= 0 && t[first - 1] - t[a - 1] <= DET_RIPPLE_SPAN_S) {
        long j = a - 1;
        double v = (x[j] - x[j - B]) / (t[j] - t[j - B]);
        if (!(fabs(v - v_ref) <= DET_RIPPLE_SPEED_SHARE * v_ref))
            break;
        a = j;
    }
    *start = a;
    return first - a >= DET_RIPPLE_MIN_SAMPLES && x[first - 1] - x[a] >= travel;
}

/* air_ripple.ripple_columns: column c (0: the first pitch's sine, 1: its cosine, ...) at position x */
static double detector_ripple_column(const DetectorFMU *s, int c, double x)
{
    double phase = (2.0 * DET_PI / s->ripple_pitches[c / 2]) * x;
    return c % 2 == 0 ? sin(phase) : cos(phase);
}

/* InterfaceDetector._entry_ripple: the drive ripple's coefficients (coef: a sine and a cosine per pitch) measured on
 * the approach before the entry's window [lo, hi] of the history (t, xs, F: n samples) -- air_ripple.measure's
 * level, trend and ripple by the normal equations; 0 where there is no pitch or too little approach */
static int detector_air_ripple(const DetectorFMU *s, const double *t, const double *xs, const double *F, long n,
                               double lo, double hi, double *coef)
{
    int P = (int)s->n_ripple, k = 2 + 2 * P;
    long first = 0, a;
    if (P <= 0)
        return 0;
    while (first < n && !(xs[first] >= lo && xs[first] <= hi))
        first++;
    double longest = 0.0;
    for (int c = 0; c < P; c++)
        longest = LOC_PYMAX(longest, s->ripple_pitches[c]);
    if (first == n || !detector_approach(t, xs, first, longest, &a))
        return 0;
    double M[LOC_MAX_COLS][LOC_MAX_COLS] = {{0.0}}, r[LOC_MAX_COLS] = {0.0}, col[LOC_MAX_COLS];
    for (long j = a; j < first; j++) {
        col[0] = 1.0;
        col[1] = t[j] - t[a];
        for (int c = 0; c < 2 * P; c++)
            col[2 + c] = detector_ripple_column(s, c, xs[j]);
        for (int i = 0; i < k; i++) {
            for (int c = 0; c < k; c++)
                M[i][c] += col[i] * col[c];
            r[i] += col[i] * F[j];
        }
    }
    loc_solve(M, r, k);
    for (int c = 0; c < 2 * P; c++) {
        if (!isfinite(r[2 + c]))
            return 0;
        coef[c] = r[2 + c];
    }
    return 1;
}

/* air_ripple.ripple_at: the measured ripple [N] at position x */
static double detector_ripple_at(const DetectorFMU *s, const double *coef, double x)
{
    double out = 0.0;
    for (int c = 0; c < 2 * (int)s->n_ripple; c++)
        out += coef[c] * detector_ripple_column(s, c, x);
    return out;
}

static void detector_locate(const Detector *d, int k, double x_trig, double lo, double hi, double h_n, double air,
                            double *out)
{
    const DetectorFMU *s = (const DetectorFMU *)d;
    out[0] = out[1] = out[2] = out[3] = out[4] = NAN;
    double *t = malloc(10 * DET_HISTORY * sizeof(double));
    if (t == NULL)
        return;
    double *x = t + DET_HISTORY, *F = x + DET_HISTORY, *xs = F + DET_HISTORY, *xsel = xs + DET_HISTORY;
    double *tsel = xsel + 2 * DET_HISTORY, *share = tsel + DET_HISTORY, *scratch = share + DET_HISTORY;
    if (k == 0 && s->entry_period > 0.0 && isfinite(d->x_ev[0]))    /* the window reaches back to the candidate */
        lo = LOC_PYMIN(lo, d->x_ev[0] - DET_ENTRY_BACK * d->locate_margin);
    double *Fsel = xsel + DET_HISTORY;
    long n = detector_history(s, h_n, t, x, F, xs), m = 0;
    int nl = (int)d->n, kind = k == 0 ? LOC_ENTRY : k == nl ? LOC_EXIT : LOC_INTERFACE;
    /* the entry's and the exit's fits in the cutting front's positions: the encoder less the drive's deflection */
    double comp = kind == LOC_EXIT || kind == LOC_ENTRY ? s->exit_compliance : 0.0;
    long upto_arm = 0;      /* the window's samples up to where the last layer's tests armed */
    double ripple[2 * DET_MAX_RIPPLE];      /* the entry's: the drive's ripple left in air (_entry_ripple) */
    int rippled = kind == LOC_ENTRY && detector_air_ripple(s, t, xs, F, n, lo, hi, ripple);
    for (long j = 0; j < n; j++)
        if (xs[j] >= lo && xs[j] <= hi) {
            upto_arm += kind == LOC_EXIT && xs[j] <= d->x_arm[k - 1];
            xsel[m] = comp > 0.0 ? xs[j] - comp * (F[j] - air) : xs[j];
            tsel[m] = t[j] - s->observer_delay;       /* when the observer saw the force (_process_change's t) */
            Fsel[m++] = rippled ? F[j] - detector_ripple_at(s, ripple, xs[j]) : F[j];
        }
    if (kind == LOC_INTERFACE && d->relative != 0.0)     /* InterfaceDetector._fit: not the gap above the layer */
        m = detector_gap_head(xsel, Fsel, tsel, m, air_offset(d) + d->floor[k - 1], -1, scratch);
    if (kind == LOC_EXIT && d->relative != 0.0 && d->F_ref - air > 0.0)   /* _exit_head_floor: not the layer's ramp */
        m = detector_gap_head(xsel, Fsel, tsel, m, air + DET_EXIT_HEAD_SHARE * (d->F_ref - air),
                              isfinite(d->x_arm[k - 1]) ? upto_arm : -1, scratch);
    if (kind == LOC_ENTRY) {
        /* InterfaceDetector._fit: a first layer pushed out inside the window ends it at its top */
        double end = event_pushed_out_end(xsel, Fsel, m, air, s->entry_period);
        if (!isnan(end)) {
            m = detector_keep_upto(end, xsel, Fsel, tsel, m);
            hi = LOC_PYMIN(hi, end);
        }
    }
    /* the engage grid fits the entry's onset, or an interface's: only the entry's may be linear alone */
    int shape = kind == LOC_ENTRY ? (int)s->entry_shape : 0;
    LocGrid engage = {s->engage_lengths, s->engage_fine, LOC_N_ENGAGE, shape == 2 ? 1 : 0, shape == 0 ? 2 : 1};
    LocGrid push = {s->push_out_lengths, s->push_out_fine, LOC_N_PUSH_OUT, 0, 2};
    if (kind == LOC_EXIT) {
        push = loc_exit_grid(&push, (int)s->exit_shape);
        push.release[0] = s->exit_release[0];
        push.release[1] = s->exit_release[1];
    }
    engage.rise_shape = s->rise_ramp != 0.0 ? (int)s->entry_shape : 0;   /* an interface's rise: the plan's ramp */
    push.rise_shape = (int)s->exit_shape;                                 /* and its push-out law */
    if (kind == LOC_ENTRY && s->entry_engagement > 0.0 && m >= 10 * LOC_MIN_SEGMENT) {
        /* InterfaceDetector._entry_ramp_max: the plan's engagement and the drive's deflection under the step */
        double first, last;
        loc_end_levels(xsel, Fsel, m, share, &first, &last);     /* share: scratch (an entry has no process change) */
        double step = LOC_PYMAX(last - air, 0.0);
        engage.n_lengths = loc_engage_count(engage.lengths, LOC_N_ENGAGE,
                                            DET_ENTRY_RAMP_SLACK * (s->entry_engagement + s->exit_release[0] * step));
    }
    /* an interface window cut short to a thin layer below may end in the gap, and a rise's gap may
     * stand above a low upper layer's air test (InterfaceDetector._fit; full: _full_loc_after) */
    double cut_floor = kind == LOC_INTERFACE && d->relative != 0.0
                       && (d->loc_after[k - 1] < d->max_gap + d->push_out + d->locate_margin
                           || d->level_plan[k] > d->level_plan[k - 1])
        ? detector_window_cut_floor(d, k) : NAN;
    /* an interface's window in the upper layer's feed's air throughout (InterfaceDetector._fit) */
    double shift = kind == LOC_INTERFACE ? detector_air_shift(s, k, tsel, m, Fsel) : 0.0;
    air -= shift;
    cut_floor -= shift;
    double period = kind == LOC_EXIT ? s->exit_period : kind == LOC_ENTRY ? s->entry_period : 0.0;
    double if_ghost[2];
    const double *ghost = kind == LOC_EXIT ? s->exit_ghost : kind == LOC_INTERFACE ? interface_ghost(s, k, if_ghost) : NULL;
    LocGrid fall_grid;
    const LocGrid *fall = kind == LOC_INTERFACE ? detector_process_change(s, k, tsel, m, &push, share, &fall_grid) : NULL;
    event_locate(kind, xsel, Fsel, m, air, x_trig, cut_floor, period, ghost, &engage, &push, fall, &out[0], &out[2]);
    if (kind == LOC_INTERFACE && isfinite(out[0])) {
        detector_gap_air(s, k, xsel, Fsel, tsel, m, air, cut_floor, out[0], scratch, &out[3]);
        out[3] += shift;
    }
    if (kind == LOC_ENTRY) {
        detector_entry_once(d, xsel, Fsel, m, hi, x_trig, air, period, &engage, &push, scratch, out);
        /* InterfaceDetector._entry_fit: again on the samples up to where the plan's first layer
         * may end past the onset (_layer_end), where the window reaches beyond */
        if (detector_layer_end(d, xsel, Fsel, m, out[0], air, period)) {
            long m2 = detector_keep_upto(out[0] + d->level_reach[0], xsel, Fsel, tsel, m);
            double fit[3], end = xsel[m2 - 1], trig = LOC_PYMIN(x_trig, end);
            event_locate(kind, xsel, Fsel, m2, air, trig, NAN, period, NULL, &engage, &push, NULL, &fit[0], &fit[2]);
            if (isfinite(fit[0])) {
                detector_entry_once(d, xsel, Fsel, m2, end, trig, air, period, &engage, &push, scratch, fit);
                if (isfinite(fit[0])) {
                    out[0] = fit[0];
                    out[2] = fit[2];
                }
            }
        }
    }
    if (k == 0 && isfinite(out[0])) {
        long a = 0;         /* the samples in air before the entry, in the window (with a span: from a margin of air) */
        double lo_air = d->entry_P != 0.0 ? LOC_PYMIN(lo, out[0] - 1.5 * d->locate_margin) : lo;
        for (long j = 0; j < n; j++)
            if (xs[j] >= lo_air && xs[j] <= hi && xs[j] < out[0] - 0.5 * d->locate_margin)
                xsel[a++] = rippled ? F[j] - detector_ripple_at(s, ripple, xs[j]) : F[j];
        detector_air_level(xsel, a, s->entry_period, &out[3]);
    }
    double t_enc = detector_time_at(t, x, n, out[0]);     /* the encoder's, unless a rule below has one */
    if (kind == LOC_EXIT)
        out[1] = detector_exit_time(s, tsel, xsel, Fsel, m, air, out[0], scratch);
    else if (kind == LOC_INTERFACE)
        out[1] = detector_interface_time(s, tsel, xsel, Fsel, m, air, t_enc - s->observer_delay, out[0]);
    if (isnan(out[1]))
        out[1] = t_enc;
    free(t);
}

/* the arrays follow the constants, in the order of DetectorFMU's comment */
static void detector_attach(DetectorFMU *s)
{
    long N = (long)s->d.N, Nm = (long)s->d.N_min;
    double *p = s->data;
    s->d.W = p;
    p += (N * (N + 1) - Nm * (Nm - 1)) / 2;
    s->d.buf = p;
    p += N;
    s->d.err = p;
    p += 2 * N;
    s->d.h_t = p;
    s->d.h_x = p + DET_HISTORY;
    s->d.h_F = p + 2 * DET_HISTORY;
    s->d.dot = NULL;
    s->d.locate = NULL;
}

/* one sample; u: F [N], x [m]; y: the block's outputs (interface_detector.py _OUTPUTS) */
void interface_detector_fmu_step(DetectorFMU *s, double t, const double *u, double *y)
{
    detector_attach(s);
    interface_detector_step(&s->d, t, u, y);
}

/* the localisation alone, for tests against event_locator.locate: kind 0 entry, 1
 * interface, 2 exit; out = x_loc, dx [m]; tables as in DetectorFMU; period [samples],
 * ghost (NULL: none), exit_shape and entry_shape (DetectorFMU's codes), release (NULL: none; the exit's
 * {compliance [m/N], x_feed}) as event_locator.locate's; share (NULL: none) an interface's process
 * change (locate's process_change: a share per sample, the law fall_shape, fall_release {compliance, x_feed});
 * cut_ripple and ramp_max [m] (NaN: none) as locate's */
void event_locate_tables(int kind, const double *x, const double *F, long n, double air, double x_trig,
                         double cut_floor, double period, const double *ghost, const double *tables, double *out,
                         int exit_shape, int entry_shape, const double *release, const double *share, int fall_shape,
                         const double *fall_release, int cut_ripple, double ramp_max)
{
    LocGrid engage = {tables, tables + LOC_N_ENGAGE, LOC_N_ENGAGE, 0, 2};
    LocGrid push = {tables + LOC_N_ENGAGE + LOC_N_FINE, tables + LOC_N_ENGAGE + LOC_N_FINE + LOC_N_PUSH_OUT,
                    LOC_N_PUSH_OUT, 0, 2};
    LocGrid fall = loc_exit_grid(&push, fall_shape);     /* the push-out lengths with the fall's law */
    if (share != NULL) {
        fall.release[0] = fall_release[0];
        fall.release[1] = fall_release[1];
        fall.share = share;
    }
    if (kind == LOC_EXIT) {
        push = loc_exit_grid(&push, exit_shape);
        if (release != NULL) {
            push.release[0] = release[0];
            push.release[1] = release[1];
        }
    }
    if (kind == LOC_ENTRY) {
        engage = loc_exit_grid(&engage, entry_shape);
        if (!isnan(ramp_max))
            engage.n_lengths = loc_engage_count(engage.lengths, LOC_N_ENGAGE, ramp_max);
    }
    engage.rise_shape = entry_shape;
    engage.cut_ripple = cut_ripple;
    push.rise_shape = exit_shape;
    event_locate(kind, x, F, n, air, x_trig, cut_floor, period, ghost, &engage, &push, share != NULL ? &fall : NULL,
                 &out[0], &out[1]);
}

/* InterfaceDetector._process_change's share alone, for the test that it is the Python's to the bit:
 * 1 with share[0..m) at the times t [s], or 0 where _process_change gives None */
int interface_detector_fmu_process_change(const DetectorFMU *s, int k, const double *t, long m, double *share)
{
    LocGrid push = {s->push_out_lengths, s->push_out_fine, LOC_N_PUSH_OUT, 0, 2}, fall;
    return detector_process_change(s, k, t, m, &push, share, &fall) != NULL;
}

/* numpy.mean as the fit spells it, for the test that it is numpy's to the bit */
double event_locator_mean(const double *a, long n)
{
    return loc_mean(a, n);
}

long interface_detector_fmu_state_size(void)
{
    return (long)sizeof(DetectorFMU);
}
