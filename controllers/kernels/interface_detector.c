/* One sample of drillcosim.controllers.interface_detector.InterfaceDetector in C (issues #21, #24).
 *
 * The same arithmetic as the Python step, operation for operation (compiled with
 * -ffp-contract=off), so both give the same doubles; the Python stays the readable
 * reference and documents every choice (tests/test_detector_kernel.py compares them).
 * Three things are not plain C arithmetic and are handed in by the block, so that the
 * doubles stay those of the Python step:
 *   - the regression's prediction is numpy's ``W @ buf``, i.e. the BLAS ddot numpy calls
 *     (OpenBLAS sums with FMA in SIMD lanes: no C loop rounds like it): ``dot``;
 *   - Python's ``sum`` of floats is a plain left sum up to 3.11 and Neumaier-compensated
 *     from 3.12: ``py_sum_comp`` says which;
 *   - the once-per-event localisation fit (controllers/event_locator.py: numpy, LAPACK)
 *     runs in Python through ``locate``, a ctypes callback, from inside the C step: a few
 *     calls per hole, each ~0.2-1 s of numpy, so every step stays a C step.
 * Scalars are doubles (flags and counts as 0.0 / 1.0 / n); the long arrays (regression
 * weights, window, history, |F~| ring) are the block's numpy arrays, by pointer.
 * Mirrored field for field by controllers/kernels/structs.py:Detector.
 */
#include <math.h>
#include <string.h>

#define MAX(a, b) ((b) > (a) ? (b) : (a))   /* Python's max(a, b): a unless b > a */
#define MIN(a, b) ((b) < (a) ? (b) : (a))   /* Python's min(a, b): a unless b < a */
#define DET_MAX_LAYERS 4
#define DET_EVENTS (DET_MAX_LAYERS + 1)      /* entry, interfaces, exit */
#define DET_HISTORY 4096                     /* interface_detector.py HISTORY */
#define DET_ENTRY_SWING 5                    /* interface_detector.py ENTRY_SWING */
#define DET_ENTRY_CANDIDATE 0.5              /* interface_detector.py ENTRY_CANDIDATE */
#define DET_LEVEL_SETTLED 0.1                /* interface_detector.py LEVEL_SETTLED */
#define DET_LEVEL_STEADY 0.5                 /* interface_detector.py LEVEL_STEADY */
#define DET_LEVEL_RISE_SHARE 0.25            /* interface_detector.py LEVEL_RISE_SHARE */
#define DET_ORBIT_STEADY 0.1                 /* interface_detector.py ORBIT_STEADY */
#define DET_AIR_OFFSET_K 2.0                 /* interface_detector.py AIR_OFFSET_K */
#define DET_AIR_GAP_QUIET 2.0                /* interface_detector.py AIR_GAP_QUIET */
#define DET_LEVEL_BAND_K 2.5                 /* interface_detector.py LEVEL_BAND_K */
#define DET_WAVE_K 4.0                       /* interface_detector.py WAVE_K */
#define DET_N_OUT 50
#define DET_PI 3.141592653589793             /* math.pi */

typedef double (*dot_fn)(long n, const double *x, long incx, const double *y, long incy);
/* k, x_trig, lo, hi [m], samples written, air level [N] -> out: x_loc, t_loc, dx, F_air, F_air_sd */
typedef void (*locate_fn)(double k, double x_trig, double lo, double hi, double h_n, double air, double *out);

typedef struct {
    /* settings */
    double n, N, N_min, thd1, thd2, thd3, exit_thinning, exit_ratio, rearm_samples, rearm_level;
    double has_windows, win_lo[DET_EVENTS], win_hi[DET_EVENTS], feed_rate, time_margin;
    double fail_disarms, mismatch_factor, restart, thd_min, thd_noise_factor, entry_confirm;
    double step_signs[DET_MAX_LAYERS - 1], relative, thd_entry, step_gain[DET_MAX_LAYERS - 1], exit_gain;
    double floor[DET_MAX_LAYERS], level_plan[DET_MAX_LAYERS];
    double level_reach[DET_MAX_LAYERS];   /* m past each layer's event its level may be taken (interface_detector.py level_reach) */
    double localise, locate_margin, push_out, max_gap;
    double py_sum_comp, loc_after[DET_MAX_LAYERS - 1], exit_after;
    double loc_sd[3];           /* m, the fit model's share of dx: entry, interfaces, exit (LOC_MODEL_SD) */
    double air_feed[DET_MAX_LAYERS];   /* m/s, the feed each layer's air level belongs to (air_feed) */
    double pass_lo[DET_MAX_LAYERS], pass_hi[DET_MAX_LAYERS], pass_feed[DET_MAX_LAYERS];   /* the air passes */
    double n_pass, pass_P;      /* air passes in use; the orbit they are measured over [samples] (0: none) */
    double pass_next;           /* state: air passes measured so far */
    double entry_P;             /* entry confirmation span [samples] (0: N_min, mean since the candidate) */
    double entry_gain;          /* the entry threshold's ramp_gain (its level test divides it out) */
    double entry_rs;            /* state: restarted after the entry before it was located */
    double x_level;             /* state: where the level the entry's restart kept began (NaN: none) */
    double entry_lag;           /* the level entry's lag [samples] (0: off) */
    double entry_ripple;        /* 1: the entry fitted again with the cut's ripple (interface_detector.py entry_ripple) */
    double lcand_t, lcand_x, lcand_i, lcand_n;   /* state: the level entry candidate (t NaN: none) */
    double h_armed;             /* state: samples written when the tests last armed */
    double x_air;               /* state: encoder travel [m] below the layer's floor since the last event */
    double exit_P;              /* the exit's orbit test: the last layer's orbit [samples] (0: off) */
    double h_event, orb_ref;    /* state: samples written at the last event; its highest orbit mean */
    double orb_sd;              /* state: the thrust's rms about that orbit mean over its orbit */
    double exit_cand_t, exit_cand_x, exit_cand_i, exit_cand_M;   /* state: the exit candidate (t NaN: none) */
    double x_arm[DET_MAX_LAYERS];   /* state: encoder position where each layer's tests first armed */
    double if_P[DET_MAX_LAYERS - 1], if_ratio[DET_MAX_LAYERS - 1];   /* the interfaces' orbit tests (0: off) */
    double if_ref;              /* state: the interface orbit test's highest orbit mean (NaN: not armed) */
    double gap_cut;             /* state: 1 once an orbit mean on the layer's cut level was seen (in_gap) */
    /* state */
    double n_buf, flag, t_ev[DET_EVENTS], x_ev[DET_EVENTS], t_paper, x_paper, t_thin, x_thin, F_ref;
    double drop, exit_armed, quiet, need, err_n, err_pos;
    double cand, cand_t, cand_x, cand_level, cand_i, cand_n, cand_sum, cand_comp;
    double cand_e[DET_ENTRY_SWING], cand_e_n, cand_e_pos;
    double armed, fail, fail_code, t_fail, x_fail, t_last, x_last, F_pred, F_err, F_level, thd, h_n;
    double n_pending, pend_k[DET_EVENTS], pend_x[DET_EVENTS], pend_i[DET_EVENTS];
    double F_air, F_air_sd, levels[DET_MAX_LAYERS], mismatch, trim, settled, steady, loc[4 * DET_EVENTS];
    double air_F[DET_MAX_LAYERS], air_S[DET_MAX_LAYERS];   /* air level [N] and spread measured at each layer's feed */
    double pass_F[DET_MAX_LAYERS], pass_S[DET_MAX_LAYERS]; /* the air passes' levels, taken at the entry's locate */
    /* the block's arrays and functions */
    const double *W;            /* weights of every window length N_min..N, one after the other */
    double *buf, *h_t, *h_x, *h_F, *err;
    dot_fn dot;
    locate_fn locate;
} Detector;

#ifdef DETECTOR_SELF_CONTAINED
/* The exported FMU (kernels/interface_detector_fmu.c) has neither numpy's BLAS nor Python:
 * it defines its own dot product and the localisation fit ported to C (event_locator.c).
 * Only that build takes this branch; the in-process step below is unchanged. */
static double detector_dot(long n, const double *w, const double *buf);
static void detector_locate(const Detector *s, int k, double x_trig, double lo, double hi, double h_n, double air,
                            double *out);
#define DET_DOT(s, n, w) detector_dot(n, w, (s)->buf)
#else
#define DET_DOT(s, n, w) (s)->dot(n, w, 1, (s)->buf, 1)
#endif

/* Python's sum() of floats, folded one term at a time: (sum, compensation) */
static void py_sum_add(const Detector *s, double *f, double *c, double x)
{
    if (s->py_sum_comp == 0.0) {
        *f += x;
        return;
    }
    double t = *f + x;
    if (fabs(*f) >= fabs(x))
        *c += (*f - t) + x;
    else
        *c += (x - t) + *f;
    *f = t;
}

static double py_sum_end(double f, double c)
{
    return (c != 0.0 && isfinite(c)) ? f + c : f;
}

/* exported for the block's check that this build sums as the running Python does */
double detector_py_sum(double compensated, const double *x, long n)
{
    Detector s;
    s.py_sum_comp = compensated;
    double f = 0.0, c = 0.0;
    for (long i = 0; i < n; i++)
        py_sum_add(&s, &f, &c, x[i]);
    return py_sum_end(f, c);
}

/* interface_detector.py _air_offset: the air level when it stands out of its spread, else 0 */
static double air_offset(const Detector *s)
{
    return fabs(s->F_air) > DET_AIR_OFFSET_K * s->F_air_sd ? s->F_air : 0.0;
}

/* interface_detector.py _refresh_air: F_air, F_air_sd measured at the current layer's feed, else at
 * the nearest feed measured (a tie: the later layer's); unchanged while none is */
static void refresh_air(Detector *s)
{
    int n = (int)s->n, j = (int)s->flag - 1, best = -1;
    double d_best = 0.0;
    j = j < 0 ? 0 : j > n - 1 ? n - 1 : j;
    for (int i = 0; i < n; i++)
        if (isfinite(s->air_F[i])) {
            double d = fabs(s->air_feed[i] - s->air_feed[j]);
            if (best < 0 || d <= d_best) {
                best = i;
                d_best = d;
            }
        }
    if (best >= 0) {
        s->F_air = s->air_F[best];
        s->F_air_sd = s->air_S[best];
    }
}

/* interface_detector.py _measure_air: an air level measured at layer j's feed, for every layer of that feed */
static void measure_air(Detector *s, int j, double F, double sd)
{
    for (int i = 0; i < (int)s->n; i++)
        if (s->air_feed[i] == s->air_feed[j]) {
            s->air_F[i] = F;
            s->air_S[i] = sd;
        }
    refresh_air(s);
}

static double hist_mean(const Detector *s, double j0, double j1);
static double hist_var(const Detector *s, double j0, double j1, double mean);

/* interface_detector.py _pass_air: the next air pass's level over its last whole orbits, for every
 * layer of its feed (taken at the events) */
static void pass_air(Detector *s)
{
    int p = (int)s->pass_next;
    s->pass_next += 1.0;
    long j1 = (long)s->h_n - 1, j0 = j1, stop = MAX((long)s->h_n - DET_HISTORY / 2, 0L);
    while (j0 > stop && s->h_x[(j0 - 1) % DET_HISTORY] >= s->pass_lo[p])
        j0--;
    if (s->pass_P >= 1.0 && (double)(j1 - j0) >= s->pass_P)
        j0 = j1 - (long)(floor((double)(j1 - j0) / s->pass_P) * s->pass_P + 0.5);
    long n = j1 - j0;
    if ((double)n < s->N_min)
        return;
    double F = hist_mean(s, (double)j0, (double)j1);
    double var = hist_var(s, (double)j0, (double)j1, F);
    double f = 0.0, c = 0.0;
    for (long j = j0 + 1; j < j1; j++) {
        double d = s->h_F[j % DET_HISTORY] - s->h_F[(j - 1) % DET_HISTORY];
        py_sum_add(s, &f, &c, d * d);
    }
    double noise = sqrt(py_sum_end(f, c) / (2.0 * (double)(n - 1)));
    double sd = sqrt(var);
    if (s->pass_P >= 1.0) {
        double ring = sqrt(2.0 * MAX(var - noise * noise, 0.0)) * MIN(1.0, s->pass_P / (DET_PI * (double)n));
        sd = MIN(sd, noise + ring);
    }
    for (int i = 0; i < (int)s->n; i++)
        if (s->air_feed[i] == s->pass_feed[p]) {
            s->pass_F[i] = F;
            s->pass_S[i] = sd;
        }
}

/* interface_detector.py _take_passes: the passes' levels for the feeds no gap has measured */
static void take_passes(Detector *s)
{
    for (int i = 0; i < (int)s->n; i++)
        if (isnan(s->air_F[i]) && isfinite(s->pass_F[i])) {
            s->air_F[i] = s->pass_F[i];
            s->air_S[i] = s->pass_S[i];
        }
    refresh_air(s);
}

/* interface_detector.py _above_air: F over the air offset */
static double above_air(const Detector *s, double F)
{
    return F - air_offset(s);
}

static double thd_interface(const Detector *s, int k, double F_pred)
{
    if (s->relative == 0.0)
        return s->thd2;
    return MAX(s->thd_min, s->step_gain[k - 1] * above_air(s, F_pred));
}

static double thd_exit(const Detector *s, double F_pred)
{
    if (s->relative == 0.0)
        return s->thd3;
    return -MAX(s->thd_min, s->exit_gain * above_air(s, F_pred));
}

static double thd_onset(const Detector *s, int k, double e, double thd)
{
    long n2 = 2 * (long)s->N;
    if (s->thd_noise_factor <= 0.0 || e * s->step_signs[k - 1] <= 0.0 || s->err_n < n2)
        return thd;
    /* the oldest N of the last 2 N |F~| (the ring is full: the oldest is at err_pos) */
    long p = (long)s->err_pos;
    double noise = s->err[p];
    for (long j = 1; j < (long)s->N; j++) {
        double v = s->err[(p + j) % n2];
        if (v > noise)
            noise = v;
    }
    return MIN(thd, MAX(s->thd_min, s->thd_noise_factor * noise));
}

/* interface_detector.py _layer_threshold: the threshold of the test the flag's layer arms */
static double layer_threshold(const Detector *s, double F_pred)
{
    int flag = (int)s->flag;
    return (1 <= flag && flag < (int)s->n) ? thd_interface(s, flag, F_pred) : -thd_exit(s, F_pred);
}

static double rearm_level(const Detector *s, double F_pred)
{
    if (s->relative == 0.0)
        return s->rearm_level;
    return MAX(s->rearm_level, 0.5 * layer_threshold(s, F_pred));
}

static double min_of(const double *v, int from, int to)
{
    double m = v[from];
    for (int i = from + 1; i < to; i++)
        if (v[i] < m)
            m = v[i];
    return m;
}

static int engaged(const Detector *s, double F_pred)
{
    int flag = (int)s->flag, n = (int)s->n;
    if (s->relative == 0.0 || !(1 <= flag && flag <= n))
        return 1;
    return above_air(s, F_pred) >= (s->fail != 0.0 ? min_of(s->floor, flag - 1, n) : s->floor[flag - 1]);
}

/* interface_detector.py _level_holds: the mean of the last N_min samples stands at F_level */
static int level_holds(const Detector *s)
{
    double M = hist_mean(s, s->h_n - s->N_min, s->h_n);
    return fabs(M - s->F_level) < MAX(s->rearm_level, DET_LEVEL_STEADY * fabs(s->F_level));
}

/* interface_detector.py _level_rises: the last N_min samples' mean above the N_min before by half the threshold */
static int level_rises(const Detector *s)
{
    double n = s->h_n, m = s->N_min;
    if (n < 2.0 * m)
        return 0;
    double rise = hist_mean(s, n - m, n) - hist_mean(s, n - 2.0 * m, n - m);
    double own = MAX(DET_LEVEL_RISE_SHARE * fabs(above_air(s, s->F_level)), 0.5 * s->rearm_level);
    return rise > MIN(0.5 * layer_threshold(s, s->F_level), own);
}

static int may_arm(const Detector *s, double x)
{
    if (s->flag == 0.0)
        return s->has_windows == 0.0 || x >= s->win_lo[0];
    if (!(s->quiet >= s->need && engaged(s, s->F_level)))
        return 0;
    /* interface_detector.py: an interface test arms on a steady level (LEVEL_STEADY) */
    return s->relative == 0.0 || s->flag >= s->n
           || (s->steady >= MIN(s->need, s->N_min) && level_holds(s) && !level_rises(s));
}

static void set_fail(Detector *s, int code, double t, double x)
{
    if (s->fail != 0.0)
        return;
    s->fail = 1.0;
    s->fail_code = code;
    s->t_fail = t;
    s->x_fail = x;
    if (s->fail_disarms != 0.0 && s->flag <= s->n) {
        s->armed = 0.0;
        s->quiet = 0.0;
        s->settled = 0.0;
        s->steady = 0.0;
    }
}

/* interface_detector.py _cut_level: not air, nor far below the plan layer's own floor */
static int cut_level(const Detector *s)
{
    double floor = min_of(s->floor, 0, (int)s->n);
    if (s->mismatch_factor > 0.0)
        floor = MAX(floor, s->floor[(int)s->flag - 1] / s->mismatch_factor);
    return above_air(s, s->F_level) >= floor;
}

/* interface_detector.py _past_gap */
static int past_gap(const Detector *s, double x)
{
    return x - s->x_last >= s->max_gap + s->locate_margin;
}

static void check_level(Detector *s, double t, double x)
{
    int k = (int)s->flag - 1, j = k - 1;
    while (j >= 0 && !(above_air(s, s->levels[j]) > 0.0))    /* the nearest layer above with a level */
        j--;
    if (!(s->mismatch_factor > 0.0 && j >= 0)) {
        s->levels[k] = s->F_level;
        return;
    }
    double ratio = (above_air(s, s->F_level) / above_air(s, s->levels[j])) / (s->level_plan[k] / s->level_plan[j]);
    /* interface_detector.py _past_gap: a level below the plan ratio may be a gap.s or a ramp.s: final past the gap */
    if (ratio < 1.0 && !past_gap(s, x))
        return;
    s->levels[k] = s->F_level;
    if (j < k - 1)      /* the gate only: the materials check is between neighbours */
        return;
    s->mismatch = ratio;
    if (!(1.0 / s->mismatch_factor <= ratio && ratio <= s->mismatch_factor))
        set_fail(s, (int)s->n + 2, t, x);
}

/* i_hist < 0: the latest sample */
static void event(Detector *s, int k, double t, double x, double i_hist)
{
    s->t_ev[k] = t;
    s->x_ev[k] = x;
    s->flag = k + 1;
    refresh_air(s);
    s->armed = 0.0;
    s->quiet = 0.0;
    s->settled = 0.0;
    s->steady = 0.0;
    s->trim = 0.0;
    s->need = s->rearm_samples;
    s->t_last = t;
    s->x_last = x;
    s->h_event = s->h_n;
    s->x_air = 0.0;
    if (s->localise != 0.0) {
        int j = (int)s->n_pending;
        s->pend_k[j] = k;
        s->pend_x[j] = x;
        s->pend_i[j] = i_hist < 0.0 ? s->h_n : i_hist;
        s->n_pending = j + 1;
    }
    if (s->has_windows != 0.0 && x < s->win_lo[k])
        set_fail(s, k + 1, t, x);
}

/* interface_detector.py _hist_mean: mean thrust of the history's samples j0..j1-1 */
static double hist_mean(const Detector *s, double j0, double j1)
{
    double f = 0.0, c = 0.0;
    for (long j = (long)j0; j < (long)j1; j++)
        py_sum_add(s, &f, &c, s->h_F[j % DET_HISTORY]);
    return py_sum_end(f, c) / (j1 - j0);
}

/* interface_detector.py _hist_var: mean square deviation from mean of the samples j0..j1-1 */
static double hist_var(const Detector *s, double j0, double j1, double mean)
{
    double f = 0.0, c = 0.0;
    for (long j = (long)j0; j < (long)j1; j++) {
        double d = s->h_F[j % DET_HISTORY] - mean;
        py_sum_add(s, &f, &c, d * d);
    }
    return py_sum_end(f, c) / (j1 - j0);
}

/* interface_detector.py _entry_air: the air level a candidate (the latest sample) is confirmed against */
static double entry_air(const Detector *s, double F_pred)
{
    double j1 = s->h_n - 1.0;
    double j0 = MAX(MAX(0.0, j1 - s->entry_P), s->h_n - DET_HISTORY);
    return (s->entry_P == 0.0 || j1 <= j0) ? F_pred : hist_mean(s, j0, j1);
}

/* interface_detector.py _entry_holds: 1 confirmed */
static int entry_holds(Detector *s)
{
    if (s->entry_P == 0.0)
        return s->cand_n >= s->N_min && py_sum_end(s->cand_sum, s->cand_comp) / s->cand_n > s->cand_level + s->thd;
    return s->cand_n >= s->entry_P
           && hist_mean(s, s->h_n - s->entry_P, s->h_n) > s->cand_level + s->thd / s->entry_gain;
}

/* interface_detector.py _entry_level: the entry of a ramp slower than the regression window */
static void entry_level(Detector *s, double t, double x)
{
    double n = s->h_n, P = s->entry_P, L = s->entry_lag;
    if (n - L - P < s->h_armed
            || hist_mean(s, n - P, n) - hist_mean(s, n - L - P, n - L) <= s->thd / s->entry_gain) {
        s->lcand_t = NAN;
    } else if (isnan(s->lcand_t)) {
        s->lcand_t = t;
        s->lcand_x = x;
        s->lcand_i = n - 1.0;
        s->lcand_n = n;
    } else if (n - s->lcand_n >= P && s->cand == 0.0) {
        double tc = s->lcand_t;
        s->lcand_t = NAN;
        event(s, 0, tc, s->lcand_x, s->lcand_i);
    }
}

static void entry_confirm(Detector *s, double t, double x, double F, double F_pred, double e)
{
    /* cand: 0 none, 1 weak (F~ past DET_ENTRY_CANDIDATE of thd only), 2 strong */
    if (s->cand == 0.0 || (e > s->thd && s->cand != 2.0)) {
        if (e > DET_ENTRY_CANDIDATE * s->thd) {
            s->cand = e > s->thd ? 2.0 : 1.0;
            s->cand_t = t;
            s->cand_x = x;
            s->cand_level = entry_air(s, F_pred);
            s->cand_i = s->h_n - 1.0;
            s->cand_n = 1.0;
            s->cand_sum = 0.0;
            s->cand_comp = 0.0;
            py_sum_add(s, &s->cand_sum, &s->cand_comp, F);
            s->cand_e[0] = e;
            s->cand_e_n = 1.0;
            s->cand_e_pos = 1.0;
        }
        return;
    }
    s->cand_n += 1.0;
    py_sum_add(s, &s->cand_sum, &s->cand_comp, F);
    int p = (int)s->cand_e_pos;
    s->cand_e[p] = e;
    s->cand_e_pos = (p + 1) % DET_ENTRY_SWING;
    if (s->cand_e_n < DET_ENTRY_SWING)
        s->cand_e_n += 1.0;
    /* sum of the last ENTRY_SWING F~, oldest first */
    int m = (int)s->cand_e_n, first = m < DET_ENTRY_SWING ? 0 : (int)s->cand_e_pos;
    double f = 0.0, c = 0.0;
    for (int j = 0; j < m; j++)
        py_sum_add(s, &f, &c, s->cand_e[(first + j) % DET_ENTRY_SWING]);
    /* interface_detector.py _entry_swings: with a span, not dropped between N_min and entry_P samples */
    int holds = entry_holds(s);     /* interface_detector.py: with a span its level decides first */
    if (py_sum_end(f, c) < 0.0 && (s->entry_P == 0.0 || s->cand_n < s->N_min || s->cand_n >= s->entry_P)
        && !(s->entry_P != 0.0 && holds)) {
        s->cand = 0.0;
    } else if (holds) {
        s->cand = 0.0;
        event(s, 0, s->cand_t, s->cand_x, s->cand_i);
        if (s->entry_P != 0.0 && s->localise != 0.0) {
            /* a span's candidate may lie in the ringing above the surface: fit around the confirmation */
            int j = (int)s->n_pending - 1;
            s->pend_x[j] = x;
            s->pend_i[j] = s->h_n;
        }
    }
}

static void exit_candidate(Detector *s, double t, double x);

/* interface_detector.py _samples_thin: the thinning test may fire on one sample where the plateau's
 * troughs (its highest orbit mean less WAVE_K rms about it) stay above the test's threshold */
static int samples_thin(const Detector *s)
{
    if (isnan(s->orb_ref))
        return 1;
    return above_air(s, s->orb_ref) - DET_WAVE_K * s->orb_sd > s->exit_ratio * above_air(s, s->F_ref);
}

/* interface_detector.py _air_known: the thinning tests' ratio over the air level needs the air measured */
static int air_known(const Detector *s)
{
    return s->relative == 0.0 || isfinite(s->F_air);
}

static void exit_tests(Detector *s, double t, double x, double F, double F_pred, double e)
{
    if (s->drop == 0.0) {
        s->F_ref = isnan(s->F_ref) ? F_pred : MAX(s->F_ref, F_pred);
        if (e < thd_exit(s, s->F_level)) {
            s->drop = 1.0;
            s->t_paper = t;
            s->x_paper = x;
            if (s->exit_thinning == 0.0)
                exit_candidate(s, t, x);
        }
    }
    if (isnan(s->t_thin) && air_known(s) && samples_thin(s) && above_air(s, F) < s->exit_ratio * above_air(s, s->F_ref)) {
        s->t_thin = t;
        s->x_thin = x;
        if (s->exit_thinning != 0.0)
            exit_candidate(s, t, x);
    }
}

/* interface_detector.py _orbit_level_fits: 1 when M may be layer k's level */
static int orbit_level_fits(const Detector *s, double M, int k)
{
    if (!(s->mismatch_factor > 0.0 && k >= 1 && above_air(s, s->levels[k - 1]) > 0.0))
        return 1;
    return above_air(s, M) <= s->mismatch_factor * above_air(s, s->levels[k - 1]) * s->level_plan[k] / s->level_plan[k - 1];
}

/* interface_detector.py _orbit_cut_level: 1 when the mean M of the last P samples may be a cut
   level of layer k (0-based) */
static int orbit_cut_level(const Detector *s, double M, double P, int k)
{
    double Ma = above_air(s, M);
    return Ma >= MAX(s->floor[k], s->thd_min)
           && hist_var(s, s->h_n - P, s->h_n, M) < Ma * Ma && orbit_level_fits(s, M, k);
}

/* interface_detector.py _orbit_arms: an orbit test of layer k arms on the last two orbit means */
static int orbit_arms(const Detector *s, double M, double P, int k)
{
    double M0;
    if (s->fail != 0.0 && s->fail_disarms != 0.0)
        return 0;
    M0 = hist_mean(s, s->h_n - 2.0 * P, s->h_n - P);
    return above_air(s, M0) >= MAX(s->floor[k], s->thd_min)
           && fabs(M - M0) < MAX(s->rearm_level, DET_ORBIT_STEADY * above_air(s, M))
           && orbit_cut_level(s, M, P, k);
}

/* interface_detector.py _exit_candidate: the one exit decision of the exit tests */
static void exit_candidate(Detector *s, double t, double x)
{
    int n = (int)s->n;
    if ((int)s->flag != n || !isnan(s->exit_cand_t))
        return;
    if (s->exit_P == 0.0 || n == 1 || past_gap(s, x)) {
        event(s, n, t, x, -1.0);
        return;
    }
    s->exit_cand_t = t;
    s->exit_cand_x = x;
    s->exit_cand_i = s->h_n;
    s->exit_cand_M = hist_mean(s, s->h_n - s->exit_P, s->h_n);
}

/* interface_detector.py _exit_confirm: decide the exit candidate (dropped on a cut level back) */
static void exit_confirm(Detector *s, double t, double x)
{
    double M = hist_mean(s, s->h_n - s->exit_P, s->h_n);
    (void)t;
    if (M >= s->exit_cand_M + s->rearm_level && orbit_cut_level(s, M, s->exit_P, (int)s->n - 1)) {
        s->exit_cand_t = s->exit_cand_x = s->exit_cand_i = s->exit_cand_M = NAN;
        s->orb_ref = s->F_ref = s->t_thin = s->x_thin = s->t_paper = s->x_paper = NAN;
        s->drop = s->armed = s->exit_armed = 0.0;
        s->quiet = s->settled = s->steady = 0.0;
    } else if (past_gap(s, x) || (s->has_windows != 0.0 && x >= s->win_hi[(int)s->n])) {
        double tc = s->exit_cand_t, xc = s->exit_cand_x, ic = s->exit_cand_i;
        s->exit_cand_t = s->exit_cand_x = s->exit_cand_i = s->exit_cand_M = NAN;
        event(s, (int)s->n, tc, xc, ic);
    }
}

/* interface_detector.py _exit_orbit: the exit's thinning test on the mean over the last orbit */
static void exit_orbit(Detector *s, double t, double x)
{
    double P = s->exit_P, M;
    if (s->h_n - s->h_event < 2.0 * P || (s->has_windows != 0.0 && x < s->win_lo[(int)s->n]))
        return;
    M = hist_mean(s, s->h_n - P, s->h_n);
    if (isnan(s->orb_ref) && !orbit_arms(s, M, P, (int)s->n - 1))
        return;
    if (!(M <= s->orb_ref)) {       /* the first or a higher orbit mean: the plateau's orbit */
        s->orb_ref = M;
        s->orb_sd = sqrt(hist_var(s, s->h_n - P, s->h_n, M));
    }
    if (air_known(s) && above_air(s, M) < s->exit_ratio * above_air(s, s->orb_ref)) {
        if (isnan(s->t_thin)) {
            s->t_thin = t;
            s->x_thin = x;
        }
        exit_candidate(s, t, x);
    }
}

/* interface_detector.py _armed_at: the first arming in a layer marks the tool on its plateau */
static void armed_at(Detector *s, double x)
{
    int flag = (int)s->flag;
    if (1 <= flag && flag <= (int)s->n && isnan(s->x_arm[flag - 1]))   /* interface_detector.py: from the kept level */
        s->x_arm[flag - 1] = flag == 1 && isfinite(s->x_level) ? MIN(x, s->x_level) : x;
}

/* interface_detector.py _in_gap: 1 when the orbit mean M says the tool left layer k (0-based) for a gap */
static int in_gap(Detector *s, double M, int k)
{
    double Ma;
    if (s->fail != 0.0 && s->fail_disarms != 0.0)
        return 0;
    Ma = above_air(s, M);
    if (Ma >= MAX(s->floor[k], s->thd_min)) {
        /* interface_detector.py _in_gap: an orbit past where the event above the layer was located */
        if (!(s->h_x[((long)s->h_n - (long)s->if_P[k]) % DET_HISTORY] < s->loc[4 * k]))
            s->gap_cut = 1.0;
        return 0;
    }
    return s->gap_cut != 0.0 && Ma < min_of(s->floor, 0, (int)s->n);
}

/* interface_detector.py _interface_orbit: interface k's drop test on the mean over the last orbit */
static void interface_orbit(Detector *s, double t, double x)
{
    int k = (int)s->flag;
    double P = s->if_P[k - 1], M;
    if (s->h_n - s->h_event < P
            || (s->has_windows != 0.0 && x < s->win_lo[k]) || (k >= 2 && isnan(s->loc[4 * (k - 1) + 3]))) {
        s->if_ref = NAN;
        s->gap_cut = 0.0;
        return;
    }
    M = hist_mean(s, s->h_n - P, s->h_n);
    if (s->max_gap > 0.0 && in_gap(s, M, k - 1)) {   /* armed or not */
        event(s, k, t, x, -1.0);
        return;
    }
    if (!isnan(s->x_arm[k - 1])) {                    /* the drop test only while the F~ tests are not armed */
        s->if_ref = NAN;
        return;
    }
    if (s->if_ratio[k - 1] == 0.0 || s->h_n - s->h_event < 2.0 * P)   /* the drop test: two orbits after the event */
        return;
    if (isnan(s->if_ref) && !orbit_arms(s, M, P, k - 1))
        return;
    s->if_ref = isnan(s->if_ref) ? M : MAX(s->if_ref, M);
    if (M < s->if_ratio[k - 1] * s->if_ref)
        event(s, k, t, x, -1.0);
}

/* interface_detector.py _predict: the regression's prediction from the window's n_buf samples */
static double predict(const Detector *s)
{
    long nb = (long)s->n_buf, Nm = (long)s->N_min;
    /* weights of length nb start after those of N_min .. nb - 1 */
    return DET_DOT(s, nb, s->W + (nb * (nb - 1) - Nm * (Nm - 1)) / 2);
}

/* interface_detector.py _count: the prediction, its error F~ = e and the arming's counts after it */
static void count(Detector *s, double F_pred, double e)
{
    s->F_pred = F_pred;
    s->F_err = e;
    if (isnan(s->F_level))
        s->F_level = F_pred;
    if (fabs(e) < rearm_level(s, s->F_level)) {
        s->quiet += 1.0;
        /* interface_detector.py LEVEL_SETTLED: the materials check's level; an armed test into a harder
           layer whose level is not taken follows only settled samples (_armed_unlevelled_rise) */
        int settled = fabs(e) < MAX(s->rearm_level, DET_LEVEL_SETTLED * fabs(F_pred));
        int flag = (int)s->flag;
        int unlevelled = s->armed != 0.0 && 1 <= flag && flag < (int)s->n && s->step_signs[flag - 1] > 0.0
                         && isnan(s->levels[flag - 1]);
        if (settled || !unlevelled)
            s->F_level = F_pred;
        s->settled = settled ? s->settled + 1.0 : 0.0;
        s->steady = fabs(e) < MAX(s->rearm_level, DET_LEVEL_STEADY * fabs(F_pred)) ? s->steady + 1.0 : 0.0;
    } else {
        s->quiet = 0.0;
        s->settled = 0.0;
        s->steady = 0.0;
        if (s->trim != 0.0 && s->n_buf > s->N_min) {
            /* interface_detector.py: keep the window's last N_min samples */
            long nb = (long)s->n_buf, Nm = (long)s->N_min;
            memmove(s->buf, s->buf + (nb - Nm), (size_t)Nm * sizeof(double));
            s->n_buf = s->N_min;
        }
    }
}

/* interface_detector.py _push: shift the regression window (oldest first) */
static void push(Detector *s, double F)
{
    long nb = (long)s->n_buf, N = (long)s->N;
    if (nb < N) {
        s->buf[nb] = F;
        s->n_buf = nb + 1;
    } else {
        memmove(s->buf, s->buf + 1, (size_t)(N - 1) * sizeof(double));
        s->buf[N - 1] = F;
    }
}

/* interface_detector.py _level_run: samples at the history's end on the level it has now */
static long level_run(const Detector *s)
{
    double j1 = s->h_n, j_min = MAX(MAX(j1 - s->N, j1 - DET_HISTORY), 0.0);
    if (j1 - j_min < s->N_min)
        return 0;
    double M = hist_mean(s, j1 - s->N_min, j1);
    double band = MAX(s->rearm_level, DET_LEVEL_BAND_K * sqrt(hist_var(s, j1 - s->N_min, j1, M)));
    long j = (long)j1 - 1;
    while (j >= (long)j_min && s->h_x[j % DET_HISTORY] >= s->x_ev[0]
            && fabs(s->h_F[j % DET_HISTORY] - M) <= band)
        j--;
    return (long)j1 - 1 - j;
}

/* interface_detector.py _replay_level: the entry's restart keeps the samples on the level */
static void replay_level(Detector *s)
{
    long m = level_run(s), Nm = (long)s->N_min;
    if (m <= Nm)
        return;
    s->x_level = s->h_x[((long)s->h_n - m) % DET_HISTORY];
    for (long j = (long)s->h_n - m; j < (long)s->h_n; j++) {
        double F = s->h_F[j % DET_HISTORY];
        if ((long)s->n_buf >= Nm) {
            double F_pred = predict(s);
            count(s, F_pred, F - F_pred);
        }
        push(s, F);
    }
}

/* the prediction error's bookkeeping and the armed test of one sample */
static void tests(Detector *s, double t, double x, double F, double F_pred)
{
    double e = F - F_pred;
    int n = (int)s->n, flag;
    count(s, F_pred, e);
    if (s->thd_noise_factor > 0.0) {
        long n2 = 2 * (long)s->N, p = (long)s->err_pos;
        s->err[p] = fabs(e);
        s->err_pos = (p + 1) % n2;
        if (s->err_n < n2)
            s->err_n += 1.0;
    }
    flag = (int)s->flag;
    if (s->relative != 0.0 && 1 <= flag && flag <= n && isnan(s->levels[flag - 1])
            && s->quiet >= s->need && s->settled >= s->N_min && cut_level(s)
            && x < s->x_ev[flag - 1] + s->x_air + s->level_reach[flag - 1] && !level_rises(s))
        check_level(s, t, x);
    flag = (int)s->flag;
    if (s->armed != 0.0 && s->relative != 0.0 && s->max_gap > 0.0 && 2 <= flag && flag < n
            && isnan(s->levels[flag - 1]) && !past_gap(s, x) && above_air(s, s->F_level) < s->floor[flag - 1]) {
        /* interface_detector.py _armed_above_layer: armed in a gap above the layer, disarmed */
        s->armed = s->quiet = s->settled = s->steady = 0.0;
        s->x_arm[flag - 1] = NAN;
    }
    if (s->armed == 0.0 && may_arm(s, x)) {
        s->armed = 1.0;
        s->trim = 0.0;
        s->h_armed = s->h_n;
        armed_at(s, x);
    }
    s->thd = NAN;
    flag = (int)s->flag;
    if (flag == 0 && s->armed != 0.0) {
        s->thd = s->relative == 0.0 ? s->thd1 : s->thd_entry;
        if (s->entry_confirm != 0.0) {
            entry_confirm(s, t, x, F, F_pred, e);
            if (s->flag == 0.0 && s->entry_lag != 0.0)
                entry_level(s, t, x);
        } else if (e > s->thd)
            event(s, 0, t, x, -1.0);
    } else if (flag < n && s->armed != 0.0) {
        /* interface_detector.py _test_level: into a harder layer no more than the layer's own level */
        double level = s->step_signs[flag - 1] > 0.0 && s->F_level > s->levels[flag - 1] ? s->levels[flag - 1] : s->F_level;
        s->thd = thd_interface(s, flag, level);
        if (fabs(e) > thd_onset(s, flag, e, s->thd))
            event(s, flag, t, x, -1.0);
    } else if (flag >= n && (s->armed != 0.0 || s->exit_armed != 0.0)) {
        s->exit_armed = 1.0;
        s->thd = -thd_exit(s, s->F_level);
        exit_tests(s, t, x, F, F_pred, e);
    }
}

/* interface_detector.py _restart_after: event k is behind the tool, restart the regression */
static void restart_after(Detector *s, int k)
{
    int n = (int)s->n;
    if (s->restart != 0.0 && k == (int)s->flag - 1 && k < n && s->armed == 0.0) {
        s->n_buf = 0.0;
        s->quiet = 0.0;
        s->settled = 0.0;
        s->steady = 0.0;
        s->need = s->N_min;
        s->trim = k + 1 < n ? 1.0 : 0.0;   /* interface_detector.py: not for the exit's test */
        if (k == 0)
            replay_level(s);
    }
}

static void locate(Detector *s, int k, double x_trig, double before, double after, double t_now)
{
    int n = (int)s->n;
    double lo = x_trig - before, out[5];
    if (k > 0 && isfinite(s->x_ev[k - 1]))
        lo = MAX(lo, s->x_ev[k - 1] + s->locate_margin);
    if (k > 0 && k < n && isfinite(s->x_arm[k - 1]))   /* interface_detector.py: below where layer k armed */
        lo = MAX(lo, s->x_arm[k - 1]);
    double air = isfinite(s->F_air) ? s->F_air : 0.0;
#ifdef DETECTOR_SELF_CONTAINED
    detector_locate(s, k, x_trig, lo, x_trig + after, s->h_n, air, out);
#else
    if (s->locate == NULL)      /* a state the block did not fill (it always sets the callback) */
        out[0] = out[1] = out[2] = out[3] = out[4] = NAN;
    else
        s->locate(k, x_trig, lo, x_trig + after, s->h_n, air, out);
#endif
    int name = k == 0 ? 0 : k == n ? DET_EVENTS - 1 : k;
    s->loc[4 * name] = out[0];
    s->loc[4 * name + 1] = out[1];
    double sd = s->loc_sd[k == 0 ? 0 : k == n ? 2 : 1];
    s->loc[4 * name + 2] = sqrt(out[2] * out[2] + sd * sd);
    s->loc[4 * name + 3] = t_now;
    if (k == 0)
        take_passes(s);
    if ((k == 0 && isfinite(out[0])) || (k > 0 && k < n && isfinite(out[3])))
        measure_air(s, k, out[3], out[4]);
    if (!(k == 0 && s->entry_rs != 0.0))
        restart_after(s, k);
}

static void locate_due(Detector *s, double t, double x)
{
    int kept = 0, m = (int)s->n_pending, n = (int)s->n;
    for (int j = 0; j < m; j++) {
        int k = (int)s->pend_k[j];
        double x_trig = s->pend_x[j], i_trig = s->pend_i[j];
        double m_ = s->locate_margin, before, after;
        if (k == 0) {
            before = m_;
            after = m_;
        } else if (k == n) {
            before = s->push_out + m_;
            after = s->exit_after;
        } else {
            before = s->max_gap + m_;
            after = s->loc_after[k - 1];
        }
        if (k == 0 && s->entry_rs == 0.0 && x >= MAX(s->x_ev[0] + m_, x_trig)) {
            restart_after(s, 0);    /* interface_detector.py _locate_due: past the candidate's engagement */
            s->entry_rs = 1.0;
        }
        if (x < x_trig + after && s->h_n - i_trig < DET_HISTORY / 2) {
            s->pend_k[kept] = k;
            s->pend_x[kept] = x_trig;
            s->pend_i[kept] = i_trig;
            kept++;
            continue;
        }
        locate(s, k, x_trig, before, after, t);
    }
    s->n_pending = kept;
}

static void check_windows(Detector *s, double t, double x)
{
    if (s->has_windows == 0.0 || s->flag > s->n || s->fail != 0.0)
        return;
    int k = (int)s->flag;
    double hi = s->win_hi[k];
    /* an entry candidate inside the window is decided first (interface_detector.py _check_windows) */
    if (x > hi && !(k == 0 && ((s->cand != 0.0 && s->cand_x <= hi) || (!isnan(s->lcand_t) && s->lcand_x <= hi)))) {
        set_fail(s, k + 1, t, x);
    } else if (s->feed_rate > 0.0 && k >= 1 && !isnan(s->x_last)) {
        double t_max = s->time_margin * MAX(hi - s->x_last, 0.0) / s->feed_rate;
        if (t - s->t_last > t_max)
            set_fail(s, k + 1, t, x);
    }
}

static void outputs(const Detector *s, double *y)
{
    int n = (int)s->n;
    double t_if[DET_MAX_LAYERS - 1], x_if[DET_MAX_LAYERS - 1];
    for (int j = 0; j < DET_MAX_LAYERS - 1; j++) {
        t_if[j] = j < n - 1 ? s->t_ev[1 + j] : NAN;
        x_if[j] = j < n - 1 ? s->x_ev[1 + j] : NAN;
    }
    double head[] = {s->flag, s->t_ev[0], t_if[0], s->t_ev[n], s->x_ev[0], x_if[0], s->x_ev[n],
                     s->fail, s->fail_code, s->F_pred, s->F_err, s->armed,
                     s->t_paper, s->x_paper, s->t_thin, s->x_thin, s->F_ref};
    int j = 0;
    for (unsigned i = 0; i < sizeof head / sizeof head[0]; i++)
        y[j++] = head[i];
    for (int i = 0; i < DET_MAX_LAYERS - 1; i++)
        y[j++] = t_if[i];
    for (int i = 0; i < DET_MAX_LAYERS - 1; i++)
        y[j++] = x_if[i];
    y[j++] = s->t_fail;
    y[j++] = s->x_fail;
    y[j++] = s->thd;
    y[j++] = s->n;
    y[j++] = s->mismatch;
    for (int i = 0; i < 4 * DET_EVENTS; i++)
        y[j++] = s->loc[i];
    y[j++] = s->F_air;
    y[j++] = s->F_air_sd;
}

/* u: F [N], x [m]; y: the block's outputs in its order (interface_detector.py _OUTPUTS) */
void interface_detector_step(Detector *s, double t, const double *u, double *y)
{
    double F = u[0], x = u[1];
    if (!isfinite(F)) {
        /* no usable force sample: keep the window and the state, only watch the windows */
        check_windows(s, t, x);
        outputs(s, y);
        return;
    }
    long i = (long)s->h_n % DET_HISTORY;
    s->h_t[i] = t;
    s->h_x[i] = x;
    s->h_F[i] = F;
    s->h_n += 1.0;
    /* a pass is measured where the tool crosses its end on the way down (InterfaceDetector.step) */
    if (s->flag == 0.0 && s->pass_next < s->n_pass && s->h_n >= 2.0
            && s->h_x[((long)s->h_n - 2) % DET_HISTORY] < s->pass_hi[(int)s->pass_next]
            && x >= s->pass_hi[(int)s->pass_next])
        pass_air(s);
    int fl = (int)s->flag;
    if (s->relative != 0.0 && 2 <= fl && fl <= (int)s->n && isnan(s->levels[fl - 1])
            && above_air(s, F) < s->floor[fl - 1])
        s->x_air += x - s->h_x[((long)s->h_n - 2) % DET_HISTORY];    /* interface_detector.py step: a gap's travel */
    if (s->n_buf >= s->N_min)
        tests(s, t, x, F, predict(s));
    if (s->exit_P != 0.0 && (int)s->flag == (int)s->n) {
        exit_orbit(s, t, x);
        if (!isnan(s->exit_cand_t))
            exit_confirm(s, t, x);
    } else if (1 <= (int)s->flag && (int)s->flag < (int)s->n && s->if_P[(int)s->flag - 1] != 0.0
               && (s->if_ratio[(int)s->flag - 1] != 0.0 || s->max_gap > 0.0))
        interface_orbit(s, t, x);
    push(s, F);                 /* after the tests, which may have trimmed the window */
    if (s->n_pending > 0.0)
        locate_due(s, t, x);
    check_windows(s, t, x);
    outputs(s, y);
}

/* sizeof(Detector), for the block's check of its ctypes mirror */
long interface_detector_state_size(void)
{
    return (long)sizeof(Detector);
}
