/* The localisation fit of controllers/event_locator.py in plain C, for the exported
 * InterfaceDetector FMU only (kernels/interface_detector_fmu.c; issue #21).
 *
 * Same model as the Python: the thrust's shape at a face (an onset ramp, linear or
 * smoothstep; a push-out falling linearly or quadratically to the air level), linear in
 * its levels for each face, length and law; the face tried on a 10 um grid and then on a
 * 1 um one around the best; the interval of the faces whose best fit is worse by less
 * than one residual variance; a gap located between the two faces around its air run.
 * The grids and their lengths are the Python's (numpy's arange spelled out; the length
 * tables are handed in, taken from event_locator.py at export). The in-process detector
 * keeps calling the Python fit (numpy's batched BLAS/LAPACK solves): this port agrees
 * with it to rounding, not to the bit (docs/export.md gives the measured agreement).
 * Every array is the caller's; scratch is allocated per call (a few calls per hole).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define LOC_MIN_SEGMENT 3          /* event_locator.MIN_SEGMENT */
#define LOC_AIR_SHARE 0.5          /* event_locator.AIR_SHARE */
#define LOC_V_DIP_SHARE 0.35       /* event_locator.V_DIP_SHARE */
#define LOC_LEVEL_SNR 3.0          /* event_locator.LEVEL_SNR */
#define LOC_NORMAL_MAD 0.6744897501960817   /* event_locator.NORMAL_MAD */
#define LOC_COARSE_STEP 10e-6      /* m, event_locator.COARSE_STEP */
#define LOC_GRID_STEP 1e-6         /* m, event_locator.GRID_STEP */
#define LOC_N_ENGAGE 25            /* len(event_locator.ENGAGE_LENGTHS) */
#define LOC_N_PUSH_OUT 30          /* len(event_locator.PUSH_OUT_LENGTHS) */
#define LOC_N_FINE 9               /* lengths tried around the best on the fine grid */
#define LOC_ENTRY 0
#define LOC_INTERFACE 1
#define LOC_EXIT 2
#define LOC_TWO_PI (2.0 * 3.141592653589793)   /* 2.0 * numpy.pi */
#define LOC_GHOST_SNR 20.0        /* event_locator.GHOST_SNR */
#define LOC_IF_GHOST_ORBIT 40.0   /* samples, event_locator.IF_GHOST_ORBIT */
#define LOC_EXIT_RING_ORBIT 40.0  /* samples, event_locator.EXIT_RING_ORBIT */
#define LOC_RELEASE_NEWTON 8      /* event_locator.RELEASE_NEWTON */
#define LOC_ENTRY_SETTLING 0.1   /* event_locator.ENTRY_SETTLING */
#define LOC_ENTRY_PUSHED_OUT 0.5 /* event_locator.ENTRY_PUSHED_OUT */
#define LOC_ENTRY_LAYER_FALL 0.9 /* event_locator.ENTRY_LAYER_FALL */
#define LOC_RUN_FEET 0.25        /* event_locator.RUN_FEET */
#define LOC_RISE_SEEN 5.0         /* event_locator.RISE_SEEN */
#define LOC_BREAK_OFF_SHARE 0.6   /* event_locator.BREAK_OFF_SHARE */
#define LOC_BREAK_OFF_FROM 0.5    /* event_locator.BREAK_OFF_FROM */
#define LOC_OUTLAST_SHARE 0.6     /* event_locator.OUTLAST_SHARE */
#define LOC_BREAK_OFF_SETTLED 0.1 /* event_locator.BREAK_OFF_SETTLED */
#define LOC_MAX_COLS 9             /* onset: level, trend, ramp, the orbit's sine and cosine, both times i / n and
                                      both times the ramp;
                                      push-out: fall, its trend, air and four ghost or ringing columns */

#define LOC_PYMAX(a, b) ((b) > (a) ? (b) : (a))   /* Python's max(a, b) */
#define LOC_PYMIN(a, b) ((b) < (a) ? (b) : (a))   /* Python's min(a, b) */

/* The length grids of one family of shapes: the coarse lengths [m] and the factors of the
 * best coarse length tried on the fine grid (numpy.geomspace(1/ratio, ratio, 9)); the
 * family's shapes first_shape .. first_shape + n_shapes - 1 are tried (0, 2: both; an
 * entry of known shape: 0, 1 linear or 1, 1 smoothstep, event_locator.ENTRY_SHAPES). */
typedef struct {
    const double *lengths, *fine;
    int n_lengths, first_shape, n_shapes;
    int rise_shape;     /* an interface's fit before a rise: the plan's code (0: any), entry_shape's for the
                           onset, exit_shape's for the free face (loc_exit_grid's codes) */
    double release[2];  /* the exit's released push-out: compliance [m/N] (0: the law itself), x_feed
                           (event_locator.locate's exit_release) */
    const double *share;   /* the push-out law's factor at each of the fit's samples, or NULL (1): an
                              interface drop's upper fall under the process change (event_locator.ProcessChange) */
    int cut_ripple;     /* an onset's fit with the cut's orbital ripple on its ramp (event_locator.locate's cut_ripple) */
} LocGrid;

/* One fit problem: samples, the family (onset or push-out), the air level (NaN: fitted);
 * period > 1 [samples]: the thrust and the model compared as their means over one orbit
 * (event_locator.orbit_mean): Fs the thrust's (m of them), work 5 n + 1 doubles of scratch. */
typedef struct {
    const double *x, *F;
    long n;
    int push_out;
    double air;
    const LocGrid *grid;
    double period;
    const double *Fs;
    long m;
    double *work;
    double orbit;                  /* samples: the ringing's sinusoid of this period (0: none; onset_face's period,
                                      free_face's ring) */
    double ghost_orbit, ghost_decay;   /* the push-out's ghost columns: orbit [samples] (0: none), decay per
                                          sample (free_face's ghost); an onset's: its cut ripple the ghost
                                          of it (onset_face's decay; orbit > 0: on) */
    int rise;                      /* onset: only a rising ramp is a fit (onset_face's rise: the entry) */
    double release_delta, release_p;   /* the push-out releases delta [m] stored at the plateau, 1 / x_feed
                                          (event_locator._release_of; delta 0: the law itself) */
} LocFit;

/* numpy's sum of a contiguous float64 array: pairwise, 8 accumulators per block of 128 */
static double loc_pairwise(const double *a, long n)
{
    if (n < 8) {
        double res = 0.0;
        for (long i = 0; i < n; i++)
            res += a[i];
        return res;
    }
    if (n <= 128) {
        double r[8], res;
        long i;
        for (int j = 0; j < 8; j++)
            r[j] = a[j];
        for (i = 8; i < n - (n % 8); i += 8)
            for (int j = 0; j < 8; j++)
                r[j] += a[i + j];
        res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
        for (; i < n; i++)
            res += a[i];
        return res;
    }
    long n2 = n / 2;
    n2 -= n2 % 8;
    return loc_pairwise(a, n2) + loc_pairwise(a + n2, n - n2);
}

/* numpy.mean of a contiguous array: its pairwise sum over the count */
static double loc_mean(const double *a, long n)
{
    if (n <= 0)
        return NAN;
    return loc_pairwise(a, n) / (double)n;
}

static int loc_cmp(const void *a, const void *b)
{
    double u = *(const double *)a, v = *(const double *)b;
    return (u > v) - (u < v);
}

/* numpy.median of n finite samples, sorting them in place */
static double loc_median_in_place(double *a, long n)
{
    qsort(a, (size_t)n, sizeof(double), loc_cmp);
    if (n % 2)
        return a[n / 2];
    return (a[n / 2 - 1] + a[n / 2]) / 2.0;
}

/* numpy.median of finite samples (scratch: n doubles) */
static double loc_median(const double *a, long n, double *scratch)
{
    memcpy(scratch, a, (size_t)n * sizeof(double));
    return loc_median_in_place(scratch, n);
}

/* numpy.std of a contiguous array (ddof 0): the root of the mean square about its mean, both
 * pairwise as numpy's (scratch: n doubles) */
static double loc_std(const double *a, long n, double *scratch)
{
    double m = loc_mean(a, n);
    for (long i = 0; i < n; i++)
        scratch[i] = (a[i] - m) * (a[i] - m);
    return sqrt(loc_mean(scratch, n));
}

/* event_locator._ghost_visible: the last fifth of F (air) scatters more than its first
 * (plateau), numpy.std, and the fall between their medians is above LOC_GHOST_SNR times the
 * plateau's scatter; scratch: n doubles */
static int loc_ghost_visible(const double *F, long n, double *scratch)
{
    long k = LOC_PYMAX(LOC_MIN_SEGMENT, n / 5);
    double sd[2] = {loc_std(F + n - k, k, scratch), loc_std(F, k, scratch)};
    double fall = loc_median(F, k, scratch) - loc_median(F + n - k, k, scratch);
    return sd[0] > sd[1] && fall > LOC_GHOST_SNR * sd[1];
}

/* numpy.arange(start, stop, step) of doubles: its length and filling (start + i * delta,
 * delta = (start + step) - start); returns the count, written to out (NULL: count only) */
static long loc_arange(double start, double stop, double step, double *out)
{
    double len = ceil((stop - start) / step);
    if (!(len > 0.0))
        return 0;
    long n = (long)len;
    if (out != NULL) {
        double delta = (start + step) - start;
        out[0] = start;
        if (n > 1)
            out[1] = start + step;
        for (long i = 2; i < n; i++)
            out[i] = start + (double)i * delta;
    }
    return n;
}

static double loc_clip01(double u)
{
    return u < 0.0 ? 0.0 : u > 1.0 ? 1.0 : u;      /* NaN stays NaN, as numpy.clip */
}

/* the push-out law of code shape (0: r, 1: r^2, 2: r^1.5) at r, clipped to [0, 1] */
static double loc_push_law(int shape, double r)
{
    double u = loc_clip01(r);
    return shape == 0 ? u : shape == 1 ? u * u : pow(u, 1.5);
}

/* event_locator._ringing at sample i into c[k..k+4): the orbit's sine and cosine at phase
 * 2 pi i / orbit, and both times i / n (an amplitude changing linearly); k + 4, or k without
 * an orbit */
static int loc_ring_columns(const LocFit *f, long i, double *c, int k)
{
    if (f->orbit == 0.0)
        return k;
    double phase = LOC_TWO_PI * (double)i / f->orbit;     /* numpy: 2.0 * np.pi * arange(n) / period */
    double grow = (double)i / (double)f->n;                /* numpy: arange(n) / n */
    c[k] = sin(phase);
    c[k + 1] = cos(phase);
    c[k + 2] = grow * c[k];
    c[k + 3] = grow * c[k + 1];
    return k + 4;
}

/* the design's columns at sample i: onset d = (x - x0)/L -> 1, d, shape(d); push-out
 * r = (xb - x)/L, g = shape(r) (0: r, 1: r^2, 2: r^1.5, clipped to [0, 1];
 * event_locator.EXIT_SHAPES) -> g, r g (and 1 when the air level is fitted); either followed
 * by the ringing's columns at ``orbit`` (loc_ring_columns), an onset's then by the orbit's
 * sine and cosine times its ramp */
static int loc_columns(const LocFit *f, double face, double L, int shape, long i, double *c)
{
    double xi = f->x[i];
    if (!f->push_out) {
        double d = (xi - face) / L, u = loc_clip01(d);
        c[0] = 1.0;
        c[1] = d;
        c[2] = shape == 0 ? u : u * u * (3.0 - 2.0 * u);
        int k = loc_ring_columns(f, i, c, 3);
        if (f->orbit == 0.0 || !f->grid->cut_ripple)
            return k;
        c[k] = c[2] * c[3];       /* the cut's orbital ripple, growing with the ramp (event_locator._onset_sse) */
        c[k + 1] = c[2] * c[4];
        return k + 2;
    }
    double r = (face - xi) / L, g = loc_push_law(shape, r);
    if (f->grid->share != NULL)
        g *= f->grid->share[i];          /* free_face's shape(r) * share */
    c[0] = g;
    c[1] = r * g;
    if (!isnan(f->air))
        return loc_ring_columns(f, i, c, 2);
    c[2] = 1.0;
    return loc_ring_columns(f, i, c, 3);
}

/* event_locator._onset_sse's cut ripple as the observer's ghost of it: the last two columns k - 2,
 * k - 1 (the ramp s = c[2] times the orbit's sine and cosine c[3], c[4]) become (s - lag(s)) times
 * them; *y the lag's state (s at i = 0, the samples visited in order; event_locator._lagged) */
static void loc_onset_ghost(const LocFit *f, long i, double *c, int k, double *y)
{
    double s = c[2];
    if (i == 0)
        *y = s;
    *y += (1.0 - f->ghost_decay) * (s - *y);
    c[k - 2] = (s - *y) * c[3];
    c[k - 1] = (s - *y) * c[4];
}

/* event_locator._release_step: the implicit Euler step of the released push-out, phi >= 0
 * with phi + a (phi/s)^p = prev + a, by RELEASE_NEWTON Newton steps from above the root */
static double loc_release_step(double prev, double s, double a, double p)
{
    if (!(s > 0.0))
        return 0.0;
    double b = prev + a, phi = LOC_PYMIN(b, LOC_PYMAX(prev, s));
    for (int it = 0; it < LOC_RELEASE_NEWTON; it++) {
        double u = phi / s, up = pow(u, p - 1.0);
        phi = phi - (phi + a * (up * u) - b) / (1.0 + a * p * up / s);
    }
    return phi > 0.0 ? phi : 0.0;
}

/* loc_columns with, on a push-out that releases the stored deflection (release_delta > 0),
 * the share phi (event_locator._released, with the grid's share) for g: g = phi, r g = r phi;
 * *phi the share at the sample before (the samples visited in order from i = 0) */
static int loc_push_columns(const LocFit *f, double face, double L, int shape, long i, double *c, double *phi)
{
    int k = loc_columns(f, face, L, shape, i, c);
    if (!f->push_out || !(f->release_delta > 0.0))
        return k;
    double xi = f->x[i], delta = f->release_delta, m = f->grid->share != NULL ? f->grid->share[i] : 1.0;
    /* _released's share m times the law, in the initial value and in both steps (1.0 * s is s) */
    if (i == 0) {
        *phi = m * loc_push_law(shape, (face - xi) / L);
    } else {
        double xp = f->x[i - 1], a = (xi - xp > 0.0 ? xi - xp : 0.0) / delta;
        double pred = loc_release_step(*phi, m * loc_push_law(shape, (face - xi + delta * *phi) / L), a, f->release_p);
        *phi = loc_release_step(*phi, m * loc_push_law(shape, (face - xi + delta * pred) / L), a, f->release_p);
    }
    c[0] = *phi;
    c[1] = ((face - xi) / L) * *phi;
    return k;
}

/* the exit's push-out grid: ``push``'s lengths with the law of event_locator.EXIT_SHAPES's
 * code exit_shape (0 any: linear or quadratic, 1 linear, 2 quadratic, 3 bending: r^1.5); on
 * an engage grid the ramp of ENTRY_SHAPES's code (0 any, 1 linear, 2 smoothstep) */
static LocGrid loc_exit_grid(const LocGrid *push, int exit_shape)
{
    LocGrid g = *push;
    g.first_shape = exit_shape == 0 ? 0 : exit_shape - 1;
    g.n_shapes = exit_shape == 0 ? 2 : 1;
    return g;
}

/* free_face's ghost columns (event_locator._ghost_columns) after the push-out's k at sample i:
 * the orbit's sine and cosine, and both times g - lag(g), g = c[0]; *y the lag's state (g at
 * i = 0, the samples visited in order) */
static int loc_ghost_columns(const LocFit *f, long i, double *c, int k, double *y)
{
    double g = c[0], phase = LOC_TWO_PI * (double)i / f->ghost_orbit, sn = sin(phase), cs = cos(phase);
    if (i == 0)
        *y = g;
    *y += (1.0 - f->ghost_decay) * (g - *y);
    double late = g - *y;
    c[k] = sn;
    c[k + 1] = cs;
    c[k + 2] = late * sn;
    c[k + 3] = late * cs;
    return k + 4;
}

/* event_locator.orbit_mean: the centred mean of a[0..n) over ``period`` samples (the two end
 * samples weigh the fraction left) at the n - 2 K samples with a whole period around them,
 * K = ceil(period / 2 - 1/2), into out; S: n + 1 doubles of scratch (numpy's cumsum, left
 * to right). Returns the count, 0 when the samples hold no whole period. */
static long loc_orbit_mean(const double *a, long n, double period, double *S, double *out)
{
    long K = (long)ceil(0.5 * period - 0.5);
    if (K < 1 || n <= 2 * K)
        return 0;
    double edge = 0.5 * (period + 1.0) - (double)K;
    S[0] = 0.0;
    for (long i = 0; i < n; i++)
        S[i + 1] = S[i] + a[i];
    for (long i = K; i < n - K; i++)
        out[i - K] = ((S[i + K] - S[i - K + 1]) + edge * (a[i - K] + a[i + K])) / period;
    return n - 2 * K;
}

/* solve M a = r (k <= LOC_MAX_COLS) by Gaussian elimination with partial pivoting, as LAPACK's gesv */
static void loc_solve(double M[LOC_MAX_COLS][LOC_MAX_COLS], double *r, int k)
{
    for (int j = 0; j < k; j++) {
        int p = j;
        for (int i = j + 1; i < k; i++)
            if (fabs(M[i][j]) > fabs(M[p][j]))
                p = i;
        if (p != j) {
            for (int c = 0; c < k; c++) {
                double tmp = M[j][c];
                M[j][c] = M[p][c];
                M[p][c] = tmp;
            }
            double tmp = r[j];
            r[j] = r[p];
            r[p] = tmp;
        }
        for (int i = j + 1; i < k; i++) {
            double l = M[i][j] / M[j][j];
            for (int c = j; c < k; c++)
                M[i][c] -= l * M[j][c];
            r[i] -= l * r[j];
        }
    }
    for (int j = k - 1; j >= 0; j--) {
        for (int c = j + 1; c < k; c++)
            r[j] -= M[j][c] * r[c];
        r[j] /= M[j][j];
    }
}

/* the normal equations of the fit on means over one orbit (free_face with a period): each
 * column at every sample, its orbit mean, then M = C C^T and r = C Fs over the m samples */
static void loc_orbit_columns(const LocFit *f, double face, double L, int shape, double M[LOC_MAX_COLS][LOC_MAX_COLS],
                              double *r, int *k)
{
    double c[LOC_MAX_COLS], *col = f->work, *S = col + 3 * f->n, *mean = S + f->n + 1, phi = 0.0;
    for (long i = 0; i < f->n; i++) {
        *k = loc_push_columns(f, face, L, shape, i, c, &phi);
        for (int a = 0; a < *k; a++)
            col[a * f->n + i] = c[a];
    }
    /* each row of n replaced by its m means (m < n) */
    for (int a = 0; a < *k; a++) {
        loc_orbit_mean(col + a * f->n, f->n, f->period, S, mean);
        for (long i = 0; i < f->m; i++)
            col[a * f->n + i] = mean[i];
    }
    for (long i = 0; i < f->m; i++)
        for (int a = 0; a < *k; a++) {
            r[a] += col[a * f->n + i] * f->Fs[i];
            for (int b = 0; b < *k; b++)
                M[a][b] += col[a * f->n + i] * col[b * f->n + i];
        }
}

/* residual sum of squares of the fit at one face, length and shape (_lstsq_batch): a
 * column that vanishes only drops out (the ridge of 1e-9 of the trace) */
static double loc_sse(const LocFit *f, double face, double L, int shape, double FF)
{
    double M[LOC_MAX_COLS][LOC_MAX_COLS] = {{0}}, r[LOC_MAX_COLS] = {0}, coef[LOC_MAX_COLS], c[LOC_MAX_COLS];
    int k = 3;
    if (f->period > 1.0) {
        loc_orbit_columns(f, face, L, shape, M, r, &k);
    } else {
        double lagged = 0.0, phi = 0.0;
        for (long i = 0; i < f->n; i++) {
            double Fi = f->F[i] - (isnan(f->air) ? 0.0 : f->air);
            k = loc_push_columns(f, face, L, shape, i, c, &phi);
            if (f->push_out && f->ghost_orbit > 0.0)
                k = loc_ghost_columns(f, i, c, k, &lagged);
            else if (!f->push_out && f->ghost_orbit > 0.0 && f->orbit > 0.0 && f->grid->cut_ripple)
                loc_onset_ghost(f, i, c, k, &lagged);
            for (int a = 0; a < k; a++) {
                r[a] += c[a] * Fi;
                for (int b = 0; b < k; b++)
                    M[a][b] += c[a] * c[b];
            }
        }
    }
    double trace = 0.0;
    for (int a = 0; a < k; a++)
        trace += M[a][a];
    for (int a = 0; a < k; a++) {
        M[a][a] += 1e-9 * trace + 1e-30;
        coef[a] = r[a];
    }
    loc_solve(M, coef, k);
    double fit = 0.0;
    for (int a = 0; a < k; a++)
        fit += coef[a] * r[a];
    if (f->rise && !f->push_out && !(coef[2] > 0.0))
        return INFINITY;           /* _lstsq_batch's rising: a falling ramp is no entry */
    return FF - fit;
}

/* the best residual over lengths and the grid's shapes at each position, and its length */
static void loc_best_on(const LocFit *f, const double *pos, long G, const double *lengths, int nL, double FF,
                        double *best, double *arg)
{
    for (long g = 0; g < G; g++) {
        best[g] = INFINITY;
        arg[g] = 0.0;
    }
    for (int j = 0; j < nL; j++)
        for (int shape = f->grid->first_shape; shape < f->grid->first_shape + f->grid->n_shapes; shape++)
            for (long g = 0; g < G; g++) {
                double c = loc_sse(f, pos[g], lengths[j], shape, FF);
                if (c < best[g])
                    arg[g] = lengths[j];
                best[g] = (isnan(best[g]) || isnan(c)) ? NAN : (c < best[g] ? c : best[g]);  /* numpy.minimum */
            }
}

/* numpy.argmin: the first NaN, else the first minimum */
static long loc_argmin(const double *v, long n)
{
    long i = 0;
    for (long j = 0; j < n; j++) {
        if (isnan(v[j]))
            return j;
        if (v[j] < v[i])
            i = j;
    }
    return i;
}

/* half-width [m] of the positions whose best fit is within bmin + var (at least one grid step) */
static double loc_interval(const double *pc, const double *bc, long Gc, const double *pf, const double *bf, long Gf,
                           double bound)
{
    double lo = INFINITY, hi = -INFINITY;
    for (long g = 0; g < Gc + Gf; g++) {
        double b = g < Gc ? bc[g] : bf[g - Gc], p = g < Gc ? pc[g] : pf[g - Gc];
        if (b <= bound) {
            lo = p < lo ? p : lo;
            hi = p > hi ? p : hi;
        }
    }
    if (!(hi >= lo))
        return NAN;
    return LOC_PYMAX(0.5 * (hi - lo), LOC_GRID_STEP);
}

/* _best_face: the face in [lo, hi] with the smallest residual and its half-width */
static void loc_best_face(const LocFit *f, double lo, double hi, double *face, double *half)
{
    double FF = 0.0;
    long n_fit = f->period > 1.0 ? f->m : f->n;     /* the samples the residual is over */
    *face = *half = NAN;
    for (long i = 0; i < n_fit; i++) {
        double Fi = f->period > 1.0 ? f->Fs[i] : f->F[i] - (isnan(f->air) ? 0.0 : f->air);
        FF += Fi * Fi;
    }
    long Gc = loc_arange(lo, hi + 0.5 * LOC_COARSE_STEP, LOC_COARSE_STEP, NULL);
    if (Gc <= 0)
        return;
    double *pc = malloc((size_t)(3 * Gc + 3 * 64) * sizeof(double));
    if (pc == NULL)
        return;
    double *bc = pc + Gc, *Lc = bc + Gc, *pf = Lc + Gc, *bf = pf + 64, *Lf = bf + 64;
    loc_arange(lo, hi + 0.5 * LOC_COARSE_STEP, LOC_COARSE_STEP, pc);
    loc_best_on(f, pc, Gc, f->grid->lengths, f->grid->n_lengths, FF, bc, Lc);
    long i = loc_argmin(bc, Gc);
    double lengths[LOC_N_FINE];
    for (int j = 0; j < LOC_N_FINE; j++)
        lengths[j] = Lc[i] * f->grid->fine[j];
    double a = LOC_PYMAX(lo, pc[i] - 2 * LOC_COARSE_STEP), b = LOC_PYMIN(hi, pc[i] + 2 * LOC_COARSE_STEP);
    long Gf = loc_arange(a, b + 0.5 * LOC_GRID_STEP, LOC_GRID_STEP, NULL);
    if (Gf > 0 && Gf <= 64) {       /* at most 4 coarse steps of fine steps (41) */
        loc_arange(a, b + 0.5 * LOC_GRID_STEP, LOC_GRID_STEP, pf);
        loc_best_on(f, pf, Gf, lengths, LOC_N_FINE, FF, bf, Lf);
        long j = loc_argmin(bf, Gf);
        double bmin = bf[j], var = bmin / (double)LOC_PYMAX(n_fit - 4, 1L);
        *face = pf[j];
        *half = loc_interval(pc, bc, Gc, pf, bf, Gf, bmin + var);
    }
    free(pc);
}

/* how many samples the first and the last fifth of the window's travel hold, at least
 * MIN_SEGMENT each (event_locator._fifths) */
static void loc_fifths(const double *x, long n, long *k0, long *k1)
{
    double span = 0.2 * (x[n - 1] - x[0]);
    *k0 = *k1 = 0;
    for (long i = 0; i < n; i++) {
        *k0 += x[i] <= x[0] + span;
        *k1 += x[i] >= x[n - 1] - span;
    }
    *k0 = LOC_PYMAX((long)LOC_MIN_SEGMENT, *k0);
    *k1 = LOC_PYMAX((long)LOC_MIN_SEGMENT, *k1);
}

/* the medians of F over the first and the last fifth of the window's travel (event_locator.end_levels) */
static void loc_end_levels(const double *x, const double *F, long n, double *scratch, double *first, double *last)
{
    long k0, k1;
    loc_fifths(x, n, &k0, &k1);
    *first = loc_median(F, k0, scratch);
    *last = loc_median(F + n - k1, k1, scratch);
}

/* event_locator.noise_spread: the median |dF| over a normal difference's (scratch: n doubles) */
static double loc_noise_spread(const double *F, long n, double *scratch)
{
    for (long i = 0; i + 1 < n; i++)
        scratch[i] = fabs(F[i + 1] - F[i]);
    return loc_median_in_place(scratch, n - 1) / (LOC_NORMAL_MAD * sqrt(2.0));
}

/* air_run: [i0, i1) of the longest run at the air level between two cut levels, or 0; the
 * levels over the first and the last fifth of the window's travel (loc_end_levels) */
static int loc_air_run(const double *x, const double *F, long n, double air, double *scratch, long *i0, long *i1)
{
    double first, last;
    loc_end_levels(x, F, n, scratch, &first, &last);
    double low = LOC_AIR_SHARE * LOC_PYMIN(first - air, last - air);
    /* a last level within LEVEL_SNR noise spreads (its own samples') of air is no cut level (event_locator.air_run) */
    long k0, k1;
    loc_fifths(x, n, &k0, &k1);
    if (!(low > 0.0) || last - air < LOC_LEVEL_SNR * loc_noise_spread(F + n - k1, k1, scratch))
        return 0;
    long best = 0, start = -1;
    *i0 = *i1 = 0;
    for (long i = 0; i <= n; i++) {
        int below = i < n && F[i] - air < low;
        if (below && start < 0)
            start = i;
        if (!below && start >= 0) {
            if (start > 0 && i - start > best) {   /* from the first sample: no cut level before it */
                best = i - start;
                *i0 = start;
                *i1 = i;
            }
            start = -1;
        }
    }
    if (best == 0 || *i1 - *i0 < 2 * LOC_MIN_SEGMENT || *i1 == n)   /* a run to the window's end: no gap */
        return 0;
    /* the run's median below half the threshold, or its middle's (RUN_FEET off either end), or a V: its lowest
     * sample below V_DIP_SHARE of it */
    long q = (long)(LOC_RUN_FEET * (double)(*i1 - *i0));
    if (loc_median(F + *i0, *i1 - *i0, scratch) - air < 0.5 * low)
        return 1;
    if (loc_median(F + *i0 + q, *i1 - *i0 - 2 * q, scratch) - air < 0.5 * low)
        return 1;
    double lowest = F[*i0];
    for (long i = *i0 + 1; i < *i1; i++)
        lowest = LOC_PYMIN(lowest, F[i]);
    return lowest - air < LOC_V_DIP_SHARE * low;
}

/* floor_gap: [i0, i1) of the longest run below cut_floor [N] after a cut level (the first
 * fifth's median above it), or 0: a window cut short to a thin lower layer that ends in the
 * gap or on the lower layer's first rise (event_locator.floor_gap) */
static int loc_floor_gap(const double *F, long n, double cut_floor, double *scratch, long *i0, long *i1)
{
    if (!isfinite(cut_floor))
        return 0;
    long k = LOC_PYMAX((long)LOC_MIN_SEGMENT, n / 5);
    if (!(loc_median(F, k, scratch) > cut_floor))
        return 0;
    /* below the floor, with fewer than 2 MIN_SEGMENT samples above it between two below counted
       below (event_locator._bridged: noise splits a gap's run about a floor of a few newtons) */
    for (long i = 0; i < n; i++)
        scratch[i] = F[i] < cut_floor;
    for (long i = 1, a = -1; i < n; i++) {
        if (scratch[i] == 0.0 && scratch[i - 1] != 0.0)
            a = i;                           /* a run above starts after one below */
        if (scratch[i] != 0.0 && scratch[i - 1] == 0.0 && a >= 0) {
            if (i - a < 2 * LOC_MIN_SEGMENT)
                for (long j = a; j < i; j++)
                    scratch[j] = 1.0;
            a = -1;
        }
    }
    long best = 0, start = -1;
    *i0 = *i1 = 0;
    for (long i = 0; i <= n; i++) {
        int below = i < n && scratch[i] != 0.0;
        if (below && start < 0)
            start = i;
        if (!below && start >= 0) {
            if (i - start > best) {          /* the first of the longest, as numpy.argmax */
                best = i - start;
                *i0 = start;
                *i1 = i;
            }
            start = -1;
        }
    }
    return best > 0 && *i1 - *i0 >= 2 * LOC_MIN_SEGMENT && *i0 >= 2 * LOC_MIN_SEGMENT;
}

/* the samples with lo <= x <= hi (a numpy mask), written to xo, Fo; returns their count */
static long loc_select(const double *x, const double *F, long n, double lo, double hi, double *xo, double *Fo)
{
    long m = 0;
    for (long i = 0; i < n; i++)
        if (x[i] >= lo && x[i] <= hi) {
            xo[m] = x[i];
            Fo[m++] = F[i];
        }
    return m;
}

/* event_locator._first_at: the first sample whose x reaches pos (n: none) */
static long loc_first_at(const double *x, long n, double pos)
{
    long i = 0;
    while (i < n && !(x[i] >= pos))
        i++;
    return i;
}

/* event_locator._from_sample: the samples from ``first`` on, in time (a layer's samples follow its
 * start in time; the encoder steps back as a broken-off layer's frame rings) */
static long loc_from(const double *x, const double *F, long n, long first, double *xo, double *Fo)
{
    long m = 0;
    for (long i = first; i < n; i++) {
        xo[m] = x[i];
        Fo[m++] = F[i];
    }
    return m;
}

/* event_locator._ghost_drop: an interface's window drops onto a lower cut level at an orbit
 * (ghost[0] samples) of at least LOC_IF_GHOST_ORBIT within the window, decay ghost[1] in [0, 1) */
static int loc_ghost_drop(const double *x, const double *F, long n, const double *ghost, double *scratch)
{
    double first, last;
    loc_end_levels(x, F, n, scratch, &first, &last);
    return LOC_IF_GHOST_ORBIT <= ghost[0] && ghost[0] <= (double)n && ghost[1] >= 0.0 && ghost[1] < 1.0 &&
           last < first;
}

/* event_locator._beyond_a_sample's median travel per sample of x (n samples; scratch: 2 n doubles) */
static double loc_median_travel(const double *x, long n, double *scratch)
{
    double *dx = scratch + n;
    for (long i = 0; i + 1 < n; i++)
        dx[i] = x[i + 1] - x[i];
    return loc_median(dx, n - 1, scratch);
}

/* event_locator._release_of: a push-out (the exit's, a drop's upper fall) releases delta =
 * compliance times the window's fall between its end levels when delta is above the median
 * travel per sample */
static void loc_release_of(LocFit *f)
{
    f->release_delta = 0.0;
    if (!(f->grid->release[0] > 0.0) || f->n < 2)
        return;
    double *scratch = malloc((size_t)(2 * f->n) * sizeof(double));
    if (scratch == NULL)
        return;
    double first, last;
    loc_end_levels(f->x, f->F, f->n, scratch, &first, &last);
    double delta = f->grid->release[0] * LOC_PYMAX(first - last, 0.0);
    if (delta > loc_median_travel(f->x, f->n, scratch)) {
        f->release_delta = delta;
        f->release_p = 1.0 / f->grid->release[1];
    }
    free(scratch);
}

/* event_locator.break_off: where an interface's upper layer broke off, out[0] the time the thrust
 * (F at times t, positions x: n samples) fell through the middle of the level it broke from (over
 * air), out[1] the first sample's time from there within LOC_BREAK_OFF_SETTLED of the step (the
 * first fifth's level less air, storing more deflection at ``compliance`` than the median travel
 * per sample), out[2] that sample's position, out[3] the level it broke from; 0 (out unset) where the fall is none: no such step, or no two samples fall by
 * LOC_BREAK_OFF_SHARE of the level they start from, that level at least LOC_BREAK_OFF_FROM of
 * the step */
static int loc_break_off(const double *t, const double *x, const double *F, long n, double air, double compliance,
                         double *out)
{
    if (n <= 2)
        return 0;
    double *scratch = malloc((size_t)(2 * n) * sizeof(double));
    if (scratch == NULL)
        return 0;
    double first, last;
    loc_end_levels(x, F, n, scratch, &first, &last);
    double step = first - air, travel = loc_median_travel(x, n, scratch);
    free(scratch);
    if (!(step > 0.0 && compliance * step > travel))
        return 0;
    long j = 2;
    double level = 0.0;
    for (; j < n; j++) {
        level = F[j - 2] - air;
        if (level >= LOC_BREAK_OFF_FROM * step && F[j - 2] - F[j] >= LOC_BREAK_OFF_SHARE * level)
            break;
    }
    if (j >= n)
        return 0;
    double mid = air + 0.5 * level;
    long k = F[j - 1] < mid ? j - 1 : j;
    out[0] = t[k - 1] + (t[k] - t[k - 1]) * (F[k - 1] - mid) / (F[k - 1] - F[k]);
    long i = k;
    while (i < n && !(F[i] <= air + LOC_BREAK_OFF_SETTLED * step))
        i++;
    i = i < n ? i : n - 1;
    out[1] = t[i];
    out[2] = x[i];
    out[3] = level;
    return 1;
}

/* event_locator._drop_fall: the grid of the upper layer's free face on the window's samples
 * x <= hi: on a drop (``drop``: the whole window's last level below its first), or where the
 * process changed before the run at air (x < ``run_start``), where the plan knows the process
 * (``fall``: its law, release and share per sample of the window), the fall's with the share of
 * those samples (written to share_up); else ``law``, the free laws */
static LocGrid loc_upper_grid(const LocGrid *law, const LocGrid *fall, int drop, const double *x, long n, double hi,
                              double run_start, double *share_up)
{
    if (fall == NULL)
        return *law;
    LocGrid g = *fall;
    long m = 0, first = -1;
    int changed = 0;
    for (long i = 0; i < n; i++) {
        if (x[i] <= hi)              /* loc_select's samples, Python's up = x <= hi */
            share_up[m++] = fall->share[i];
        if (x[i] < run_start) {      /* the process changed before the run at air: on the upper fall */
            if (first < 0)
                first = i;
            changed |= fall->share[i] != fall->share[first];
        }
    }
    if (!drop && !changed)           /* a rise whose trigger came past the upper layer's fall */
        return *law;
    g.share = share_up;
    return g;
}

/* event_locator._drop_onset: the lower layer's onset in [lo, the last sample] on f's samples with
 * ``ramp``, a rising one; on its bound lo with a drop's free ramps (``free_ramps``: not the plan's), again
 * with ``plan_ramp`` */
static void loc_drop_onset(LocFit *f, const LocGrid *ramp, const LocGrid *plan_ramp, int free_ramps, double lo,
                           double *hi, double *dhi)
{
    f->rise = 1;
    f->grid = ramp;
    loc_best_face(f, lo, f->x[f->n - 1], hi, dhi);
    if (*hi <= lo && free_ramps) {
        f->grid = plan_ramp;
        loc_best_face(f, lo, f->x[f->n - 1], hi, dhi);
    }
}

/* event_locator._rise_before_change: where the down samples rise (their own end levels) and the
 * process changes inside them (``share``, down's, leaves its first value) after the ramp's foot
 * shows (the last sample before the change above the gap's F[g0..g1) median by LOC_RISE_SEEN
 * standard deviations), the onset on the samples before the change replaces *hi, *dhi if it is past
 * lo with 2 MIN_SEGMENT of them past it: the ramp's rest is the new feed per revolution's, bent by
 * the drive's release and the observer's lag, and fitted through it the onset came late */
static void loc_rise_before_change(const LocFit *down, const double *share, const double *gap, long n_gap,
                                   const LocGrid *ramp, const LocGrid *plan_ramp, int free_ramps, double lo,
                                   double *scratch, double *hi, double *dhi)
{
    double first, last;
    loc_end_levels(down->x, down->F, down->n, scratch, &first, &last);
    long c = 0;
    while (c < down->n && share[c] == share[0])    /* numpy's share != share[0]: the first that leaves it */
        c++;
    if (!(last > first) || c == down->n || c == 0)
        return;
    double seen = loc_median(gap, n_gap, scratch) + LOC_RISE_SEEN * loc_std(gap, n_gap, scratch);
    if (!(down->F[c - 1] > seen))
        return;
    LocFit before = *down;
    double h, dh;
    long past = 0;
    before.n = c;
    loc_drop_onset(&before, ramp, plan_ramp, free_ramps, lo, &h, &dh);
    for (long i = 0; i < c; i++)
        past += down->x[i] > h;
    if (h > lo && past >= 2 * LOC_MIN_SEGMENT) {
        *hi = h;
        *dhi = dh;
    }
}

/* event_locator._rise_threshold: the gap's second half's level plus LOC_RISE_SEEN noise spreads of
 * the run F[g0..g1) */
static double loc_rise_threshold(const double *F, long g0, long g1, double *scratch)
{
    long half = (g1 - g0) / 2;
    double level = loc_median(F + g0 + half, g1 - g0 - half, scratch);
    return level + LOC_RISE_SEEN * loc_noise_spread(F + g0, g1 - g0, scratch);
}

/* event_locator._onset_on_the_fall: the free face lo pinned at the onset hi (within two grid steps)
 * and the 2 MIN_SEGMENT samples' mean after hi below the one before by two standard errors of the
 * run's noise */
static int loc_onset_on_the_fall(const double *x, const double *F, long n, long g0, long g1, double lo,
                                 double hi, double *scratch)
{
    long i = loc_first_at(x, n, hi), m = 2 * LOC_MIN_SEGMENT;
    if (!(lo >= hi - 2.0 * LOC_GRID_STEP) || i < m || i + m > n)
        return 0;
    double se = loc_noise_spread(F + g0, g1 - g0, scratch) * sqrt(2.0 / (double)m);
    return loc_mean(F + i, m) < loc_mean(F + i - m, m) - 2.0 * se;
}

/* event_locator._first_run: the first sample, from ``start`` on, of 2 MIN_SEGMENT in a row above
 * ``thr`` (the rise threshold: where the thrust rises out of the gap); -1: none */
static long loc_first_run(const double *F, long n, double thr, long start)
{
    long m = 2 * LOC_MIN_SEGMENT, held = 0;
    for (long i = start; i < n; i++) {
        held = F[i] > thr ? held + 1 : 0;
        if (held == m)
            return i - m + 1;
    }
    return -1;
}

/* event_locator._v_foot: where the run F[g0..g1) holds the lower ramp (a V), 1 with *low its lowest
 * sample before ``onset`` (the first such) and *thr the median of the 2 MIN_SEGMENT samples about it
 * plus LOC_RISE_SEEN noise spreads of the run, which the run's second half's median stands above;
 * else 0 (scratch: n doubles) */
static int loc_v_foot(const double *x, const double *F, long n, long g0, long g1, double onset, double *scratch,
                      long *low, double *thr)
{
    long j = loc_first_at(x, n, onset);  /* numpy.searchsorted(x, onset) */
    if (j > g1)
        j = g1;
    if (j <= g0)
        return 0;
    long b = g0;
    for (long k = g0 + 1; k < j; k++)
        if (F[k] < F[b])
            b = k;
    long a = LOC_PYMAX(g0, b - LOC_MIN_SEGMENT), e = LOC_PYMIN(n, b + LOC_MIN_SEGMENT);
    double t = loc_median(F + a, e - a, scratch) + LOC_RISE_SEEN * loc_noise_spread(F + g0, g1 - g0, scratch);
    long half = (g1 - g0) / 2;
    if (!(loc_median(F + g0 + half, g1 - g0 - half, scratch) > t))
        return 0;
    *low = b;
    *thr = t;
    return 1;
}

/* event_locator._foot_bound: on a rise (rising), *hi no later than the first sample from the
 * lowest one between the run's middle ``mid`` and *hi (_foot_from; none where it stands above the
 * gap's level) from which 2 MIN_SEGMENT samples in a row stand LOC_RISE_SEEN noise spreads (the run
 * F[g0..g1)'s) above the median of the run's second half: a rise cannot start after its thrust
 * stands out of the gap (scratch: n doubles) */
static void loc_foot_bound(const double *x, const double *F, long n, long g0, long g1, double mid, int rising,
                           double *scratch, double *hi, double *dhi)
{
    if (!rising)
        return;
    double thr;
    long low;
    if (!loc_v_foot(x, F, n, g0, g1, *hi, scratch, &low, &thr)) {
        thr = loc_rise_threshold(F, g0, g1, scratch);
        long i = loc_first_at(x, n, mid), end = loc_first_at(x, n, *hi);   /* numpy.searchsorted */
        if (end <= i)
            return;
        low = i;                             /* _foot_from: the lowest sample before the onset (the first) */
        for (long k = i + 1; k < end; k++)
            if (F[k] < F[low])
                low = k;
        if (F[low] > thr)                    /* above the gap's level: no foot to bound */
            return;
    }
    long j = loc_first_run(F, n, thr, low);
    if (j < 0 || !(x[j] < *hi))
        return;
    *hi = x[j];
    *dhi = LOC_PYMAX(*dhi, x[j] - x[j - 1]);
}

/* event_locator._upper_face: the upper layer's free face in [x[0], bound] on the samples x <= bound,
 * under the grid loc_upper_grid gives (``law``, or on a drop the process's ``change``), released */
static void loc_upper_face(const double *x, const double *F, long n, double air, const LocGrid *law,
                           const LocGrid *change, int drop, double bound, double run_start, double *xu, double *Fu,
                           double *share_up, double *lo, double *dlo)
{
    long n_up = loc_select(x, F, n, -INFINITY, bound, xu, Fu);
    LocGrid upper = loc_upper_grid(law, change, drop, x, n, bound, run_start, share_up);
    LocFit up = {xu, Fu, n_up, 1, air, &upper};
    loc_release_of(&up);                 /* the fall's release on the up samples (_upper_face); else none */
    loc_best_face(&up, x[0], bound, lo, dlo);
}

/* a gap: the upper layer's free face and the lower one's onset around the air run; ``change``
 * (NULL: none) the adaptation's process change at the trigger (its share per sample of x): a drop's
 * upper fall under it (loc_upper_grid), a rise's onset before it (loc_rise_before_change) */
static void loc_gap(const double *x, const double *F, long n, double air, long g0, long g1, int open_end,
                    const LocGrid *engage, const LocGrid *push, const LocGrid *change, double *x_loc, double *dx)
{
    double mid = 0.5 * (x[g0] + x[g1 - 1]);
    double *xu = malloc((size_t)(7 * n) * sizeof(double));
    if (xu == NULL)
        return;
    double *Fu = xu + n, *xd = Fu + n, *Fd = xd + n, *scratch = Fd + n, *share_up = scratch + n,
           *share_down = share_up + n;
    long n_up = loc_select(x, F, n, -INFINITY, mid, xu, Fu), n_down = loc_select(x, F, n, mid, INFINITY, xd, Fd);
    if (n_up >= 2 * LOC_MIN_SEGMENT && n_down >= 2 * LOC_MIN_SEGMENT) {
        /* the lower layer's level from the air run's start when it cuts higher than the upper
           one; a drop whose run ends 2 MIN_SEGMENT samples before the window: its onset
           searched from there too (event_locator._onset_from) */
        double first, last;
        loc_end_levels(x, F, n, scratch, &first, &last);
        int closed_drop = last < first && g1 <= n - 2 * LOC_MIN_SEGMENT;
        long first_down = last > first || closed_drop ? g0 : loc_first_at(x, n, mid);
        n_down = loc_from(x, F, n, first_down, xd, Fd);
        double lo_onset = closed_drop ? x[g0] : mid;
        /* before a rise the plan's ramp and push-out law (event_locator._rise_laws); a drop's
           free ramps, the plan's on the onset's bound (_drop_onset) */
        LocGrid plan_ramp = loc_exit_grid(engage, engage->rise_shape);
        LocGrid ramp = last > first ? plan_ramp : *engage;
        LocGrid law = last > first ? loc_exit_grid(push, push->rise_shape) : *push;
        int free_ramps = !(last > first) && engage->rise_shape != 0;
        LocFit down = {xd, Fd, n_down, 0, NAN, &ramp};
        double lo, dlo, hi, dhi;
        if (open_end) {                      /* the window ends in the gap: the run's last sample bounds it */
            hi = x[g1 - 1];
            dhi = 0.0;
        } else {
            loc_drop_onset(&down, &ramp, &plan_ramp, free_ramps, lo_onset, &hi, &dhi);
            if (change != NULL) {            /* the share of the down samples, Python's change.share[down] */
                loc_from(x, change->share, n, first_down, xu, share_down);
                loc_rise_before_change(&down, share_down, F + g0, g1 - g0, &ramp, &plan_ramp, free_ramps, lo_onset,
                                       scratch, &hi, &dhi);
            }
            loc_foot_bound(x, F, n, g0, g1, mid, last > first, scratch, &hi, &dhi);
        }
        /* the upper layer's fall up to the lower layer's onset (event_locator._gap_faces) */
        loc_upper_face(x, F, n, air, &law, change, last < first, hi, x[g0], xu, Fu, share_up, &lo, &dlo);
        if (!open_end && closed_drop && lo > x[g0]) {
            /* the onset's level from the run's start held the upper fall's tail: the onset
               again from the free face on, kept only where earlier: the tail taken out, never
               a later ramp (event_locator._gap_faces) */
            double hi2, dhi2;
            down.n = loc_from(x, F, n, loc_first_at(x, n, lo), xd, Fd);
            loc_drop_onset(&down, &ramp, &plan_ramp, free_ramps, lo, &hi2, &dhi2);
            if (hi2 < hi) {
                hi = hi2;
                dhi = dhi2;
            }
        }
        if (!open_end && loc_onset_on_the_fall(x, F, n, g0, g1, lo, hi, scratch)) {
            /* the onset lay on the upper fall: the free face up to the rise out of the gap, the onset
               from there (event_locator._past_the_fall) */
            long b = loc_first_run(F, n, loc_rise_threshold(F, g0, g1, scratch), loc_first_at(x, n, lo));
            if (b >= 0) {
                double lo2, dlo2, hi2, dhi2;
                loc_upper_face(x, F, n, air, &law, change, last < first, x[b], x[g0], xu, Fu, share_up, &lo2, &dlo2);
                down.n = loc_from(x, F, n, loc_first_at(x, n, lo2), xd, Fd);
                loc_drop_onset(&down, &ramp, &plan_ramp, free_ramps, lo2, &hi2, &dhi2);
                if (lo < lo2 && lo2 <= hi2) {
                    lo = lo2;
                    dlo = dlo2;
                    hi = hi2;
                    dhi = dhi2;
                }
            }
        }
        *x_loc = 0.5 * (lo + hi);
        *dx = 0.5 * fabs(hi - lo) + LOC_PYMAX(dlo, dhi);
    }
    free(xu);
}

/* the exit's free face (locate, kind exit), on means over one orbit of ``period`` samples
 * when the window holds one orbit and 10 MIN_SEGMENT samples more */
static void loc_exit(LocFit *f, double period, double x0, double x1, double *x_loc, double *dx)
{
    double *Fs = NULL;
    loc_release_of(f);
    if (period > 1.0 && (double)f->n >= period + 10 * LOC_MIN_SEGMENT) {
        Fs = malloc((size_t)(7 * f->n + 2) * sizeof(double));
        if (Fs == NULL)
            return;
        f->work = Fs + f->n;
        f->m = loc_orbit_mean(f->F, f->n, period, f->work, Fs);
        f->Fs = Fs;
        f->period = f->m > 0 ? period : 0.0;
        f->orbit = 0.0;                 /* free_face: no ringing columns on orbit means */
    }
    loc_best_face(f, x0, x1, x_loc, dx);
    free(Fs);
}

/* event_locator._ghost_decay: a ghost given (non-NULL) with an orbit of more than one sample and a
 * decay per sample in [0, 1) */
static int loc_ghost_valid(const double *ghost)
{
    return ghost != NULL && ghost[0] > 1.0 && ghost[1] >= 0.0 && ghost[1] < 1.0;
}

/* event_locator.locate: position [m] and uncertainty [m] of an event of ``kind`` from
 * samples x [m] (increasing), F [N]; NaN when there are too few. cut_floor [N]: NaN, or an
 * interface window cut short to a thin layer below (event_locator.floor_gap); period
 * [samples]: the exit's fit on means over one orbit, the entry's fits the orbit's sinusoid
 * too (<= 1: none; locate's period); ghost: NULL, or the exit's {orbit [samples], decay per
 * sample} of locate's ghost, or an interface's (the lower layer's orbit); change: NULL, or the
 * adaptation's process change at an interface's trigger (locate's process_change: a push-out grid
 * of the plan's law and release with the share per sample of x_in; a drop's upper fall under it, a
 * rise's onset before it) */
void event_locate(int kind, const double *x_in, const double *F_in, long n_in, double air, double x_trig,
                  double cut_floor, double period, const double *ghost, const LocGrid *engage, const LocGrid *push,
                  const LocGrid *change, double *x_loc, double *dx)
{
    *x_loc = *dx = NAN;
    double *x = malloc((size_t)(4 * (n_in > 0 ? n_in : 1)) * sizeof(double));
    if (x == NULL)
        return;
    double *F = x + n_in, *scratch = F + n_in, *share = scratch + n_in;
    long n = 0;
    for (long i = 0; i < n_in; i++)
        if (isfinite(x_in[i]) && isfinite(F_in[i])) {
            if (change != NULL)
                share[n] = change->share[i];    /* _checked_change: the share of the samples kept */
            x[n] = x_in[i];
            F[n++] = F_in[i];
        }
    LocGrid change_kept = change != NULL ? *change : *push, *kept = change != NULL ? &change_kept : NULL;
    change_kept.share = share;
    long g0, g1;
    if (n < 5 * LOC_MIN_SEGMENT * 2) {
        free(x);
        return;
    }
    double x0 = x[0], x1 = x[n - 1];
    LocFit onset = {x, F, n, 0, NAN, engage, 0.0, NULL, 0, NULL, 0.0}, exit_ = {x, F, n, 1, NAN, push, 0.0, NULL, 0, NULL, 0.0};
    if (kind == LOC_ENTRY && period > 1.0 && period <= (double)n)
        onset.orbit = period;       /* event_locator.locate: the entry's window holds one orbit */
    onset.rise = kind == LOC_ENTRY;     /* event_locator.locate: an entry's ramp rises */
    if (kind == LOC_ENTRY && engage->cut_ripple && loc_ghost_valid(ghost)) {
        onset.ghost_orbit = ghost[0];   /* event_locator.locate: the entry's cut ripple as the observer's ghost */
        onset.ghost_decay = ghost[1];
    }
    if (kind == LOC_EXIT && loc_ghost_valid(ghost) && ghost[0] <= (double)n) {   /* locate: the exit's window holds one orbit */
        if (loc_ghost_visible(F, n, scratch)) {   /* ... and shows a ghost */
            exit_.ghost_orbit = ghost[0];
            exit_.ghost_decay = ghost[1];
        } else if (ghost[0] >= LOC_EXIT_RING_ORBIT) {
            exit_.orbit = ghost[0];     /* ... else at a slow orbit the observer's ringing is fitted */
        }
    }
    int air_gap = 0, floor_gap = 0;
    if (kind == LOC_INTERFACE) {
        air_gap = loc_air_run(x, F, n, air, scratch, &g0, &g1);
        floor_gap = !air_gap && loc_floor_gap(F, n, cut_floor, scratch, &g0, &g1);
    }
    /* event_locator._outlasts_orbit: a run at the air level an orbit long is a gap, not the ringing's trough */
    int outlasts = (air_gap || floor_gap) && ghost != NULL && (double)(g1 - g0) >= LOC_OUTLAST_SHARE * ghost[0];
    if (kind == LOC_INTERFACE && ghost != NULL && !outlasts && loc_ghost_drop(x, F, n, ghost, scratch)) {
        exit_.ghost_orbit = ghost[0];   /* the upper layer's free face with the observer's ghost */
        exit_.ghost_decay = ghost[1];
        loc_best_face(&exit_, x0, x1, x_loc, dx);
    } else if (kind == LOC_EXIT)
        loc_exit(&exit_, period, x0, x1, x_loc, dx);
    else if (air_gap)
        loc_gap(x, F, n, air, g0, g1, 0, engage, push, kept, x_loc, dx);
    else if (floor_gap)
        loc_gap(x, F, n, NAN, g0, g1, n - g1 < 2 * LOC_MIN_SEGMENT, engage, push, kept,
                x_loc, dx);   /* air fitted */
    else
        loc_best_face(&onset, x0, LOC_PYMIN(x_trig, x1), x_loc, dx);
    free(x);
}

/* event_locator.engage_lengths: how many of the (increasing) lengths are up to ramp_max [m], at least one */
static int loc_engage_count(const double *lengths, int n, double ramp_max)
{
    int k = 0;
    while (k < n && lengths[k] <= ramp_max)
        k++;
    return LOC_PYMAX(1, k);
}

/* event_locator.onset_length: the ramp length [m] of the engage grid's coarse lengths that fits
 * an entry's samples (finite) best with its onset at x0 [m], period [samples] as event_locate's
 * entry; NaN where no rising ramp fits */
double event_onset_length(const double *x, const double *F, long n, double x0, double period, const LocGrid *engage)
{
    LocFit onset = {x, F, n, 0, NAN, engage, 0.0, NULL, 0, NULL, 0.0};
    if (period > 1.0 && period <= (double)n)
        onset.orbit = period;
    onset.rise = 1;
    double FF = 0.0, best, L;
    for (long i = 0; i < n; i++)
        FF += F[i] * F[i];
    loc_best_on(&onset, &x0, 1, engage->lengths, engage->n_lengths, FF, &best, &L);
    return isfinite(best) ? L : NAN;
}

/* event_locator.settling_fall: the thrust's fall after an entry's ramp (onset x0 [m], ramp [m])
 * as a share of its step, means over span [m]; NaN where the window holds no two spans after the
 * ramp's top or nothing before the onset */
double event_settling_fall(const double *x, const double *F, long n, double x0, double ramp, double span)
{
    double top = x0 + ramp, sum[3] = {0.0, 0.0, 0.0};
    long cnt[3] = {0, 0, 0};
    if (!(n > 0 && x[n - 1] - span > top + span))
        return NAN;
    for (long i = 0; i < n; i++) {
        int in[3] = {x[i] >= top && x[i] <= top + span, x[i] >= x[n - 1] - span, x[i] <= x0};
        for (int j = 0; j < 3; j++)
            if (in[j]) {
                sum[j] += F[i];
                cnt[j]++;
            }
    }
    if (cnt[0] == 0 || cnt[2] == 0)
        return NAN;
    double A = sum[0] / (double)cnt[0], Z = sum[2] / (double)cnt[2];
    return A > Z ? (A - sum[1] / (double)cnt[1]) / (A - Z) : NAN;
}

/* event_locator.orbit_fell: the last position [m] of the orbit (period samples) with the highest
 * mean thrust where the window's last orbit mean is below ``share`` of that mean's step over air;
 * NaN otherwise (or no whole orbit or period) */
double event_orbit_fell(const double *x, const double *F, long n, double air, double period, double share)
{
    if (!(1.0 < period && (double)n > period + 2.0))
        return NAN;
    double *S = malloc((2 * (size_t)n + 1) * sizeof(double));
    if (S == NULL)
        return NAN;
    double *M = S + n + 1, end = NAN;
    long m = loc_orbit_mean(F, n, period, S, M), K = (n - m) / 2, j = 0;
    for (long i = 1; i < m; i++)
        if (M[i] > M[j])
            j = i;
    if (m > 0 && M[m - 1] - air < share * (M[j] - air))
        end = x[j + 2 * K];
    free(S);
    return end;
}

/* event_locator.pushed_out_end: event_orbit_fell below LOC_ENTRY_PUSHED_OUT (a first layer pushed
 * out inside the entry's window) */
double event_pushed_out_end(const double *x, const double *F, long n, double air, double period)
{
    return event_orbit_fell(x, F, n, air, period, LOC_ENTRY_PUSHED_OUT);
}
