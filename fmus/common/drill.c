/* Drill and layered workpiece model, noise generator (see drill.h, docs/plants.md). */
#include <math.h>
#include <stdio.h>

#include "drill.h"

/* ---------------------------------------------------------------- noise */

void prng_seed(Prng *r, int64_t seed)
{
    /* splitmix64 scrambling of the seed: never a zero xorshift state */
    uint64_t z = (uint64_t)seed + 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z = z ^ (z >> 31);
    r->s = z ? z : 0x2545F4914F6CDD1Dull;
    r->has_spare = 0;
    r->spare = 0.0;
}

double prng_uniform(Prng *r)
{
    uint64_t x = r->s;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    r->s = x;
    x *= 0x2545F4914F6CDD1Dull;
    return ((double)(x >> 11) + 0.5) * (1.0 / 9007199254740992.0); /* (0,1) */
}

double prng_gauss(Prng *r)
{
    double u1, u2, rad;
    if (r->has_spare) {
        r->has_spare = 0;
        return r->spare;
    }
    u1 = prng_uniform(r);
    u2 = prng_uniform(r);
    rad = sqrt(-2.0 * log(u1));
    r->spare = rad * sin(2.0 * M_PI * u2);
    r->has_spare = 1;
    return rad * cos(2.0 * M_PI * u2);
}

/* ---------------------------------------------------------------- machine */

/* The step is snapped to whole nanoseconds when it is within 1e-3 ns of them: a master that
 * counts time in integer nanoseconds (libcosim) gives H = t_(k+1) - t_k of its doubles, the
 * decimal step a last bit or two apart, and the plant must integrate the same sub-steps as
 * under a master that gives the decimal itself. A decimal H of at most 9 fractional digits is
 * its own snap (round(H 1e9) / 1e9 is correctly rounded), so such a master sees no change. */
int substeps(double H, double h_internal, double *hs)
{
    const double H_ns = H * 1e9, whole_ns = nearbyint(H_ns);
    if (fabs(H_ns - whole_ns) <= 1e-3 && whole_ns > 0.0 && whole_ns < 9007199254740992.0) H = whole_ns / 1e9;
    int nsub = (int)ceil(H / h_internal - 1e-9);
    if (nsub < 1) nsub = 1;
    *hs = H / nsub;
    return nsub;
}

double stick_slip_friction(double F_ext, double v, double F_c, double F_s, double v_s, double b)
{
    if (v == 0.0) {
        double F_static = F_c + F_s;
        if (fabs(F_ext) <= F_static) return F_ext;
        return F_ext > 0.0 ? F_static : -F_static;
    } else {
        double x = fabs(v) / v_s;
        double Fk = F_c + (x < 6.0 ? F_s * exp(-x * x) : 0.0);
        return (v > 0.0 ? Fk : -Fk) + b * v;
    }
}

/* ---------------------------------------------------------------- validation */

#define CHECK(cond, ...) do { if (!(cond)) { snprintf(msg, n, __VA_ARGS__); return 1; } } while (0)

int drill_validate(const DrillParams *p, char *msg, size_t n)
{
    int k;
    CHECK(p->n_layers >= 1 && p->n_layers <= DRILL_MAX_LAYERS,
          "n_layers = %d is invalid: expected 1..%d", p->n_layers, DRILL_MAX_LAYERS);
    for (k = 0; k < p->n_layers; k++) {
        CHECK(p->material[k] >= 1 && p->material[k] <= 3,
              "layer%d_material = %d is invalid: expected 1 (CFRP), 2 (Ti-6Al-4V) or 3 (aluminium)",
              k + 1, p->material[k]);
        CHECK(p->thickness[k] > 0.0, "layer%d_thickness = %g m is invalid: expected > 0 for a used layer",
              k + 1, p->thickness[k]);
        CHECK(p->gap[k] >= 0.0, "layer%d_gap = %g m is invalid: expected >= 0", k + 1, p->gap[k]);
        CHECK(p->kc[k] >= 0.0, "layer%d_kc = %g N/(m/rev) is invalid: expected >= 0 (0 = material preset)",
              k + 1, p->kc[k]);
    }
    for (k = p->n_layers; k < DRILL_MAX_LAYERS; k++) {
        CHECK(p->thickness[k] >= 0.0, "layer%d_thickness = %g m is invalid: expected >= 0", k + 1, p->thickness[k]);
        CHECK(p->gap[k] >= 0.0, "layer%d_gap = %g m is invalid: expected >= 0", k + 1, p->gap[k]);
        CHECK(p->kc[k] >= 0.0, "layer%d_kc = %g N/(m/rev) is invalid: expected >= 0", k + 1, p->kc[k]);
    }
    CHECK(p->kc_cfrp > 0.0, "kc_cfrp = %g N/(m/rev) is invalid: expected > 0", p->kc_cfrp);
    CHECK(p->kc_ti > 0.0, "kc_ti = %g N/(m/rev) is invalid: expected > 0", p->kc_ti);
    CHECK(p->kc_al > 0.0, "kc_al = %g N/(m/rev) is invalid: expected > 0", p->kc_al);
    CHECK(p->ti_descent >= 0.0, "ti_descent = %g 1/m is invalid: expected >= 0", p->ti_descent);
    CHECK(p->ripple_ratio >= 0.0 && p->ripple_ratio < 1.0,
          "ripple_ratio = %g is invalid: expected 0 <= ripple_ratio < 1", p->ripple_ratio);
    CHECK(p->k_contact > 0.0, "k_contact = %g N/m is invalid: expected > 0", p->k_contact);
    CHECK(p->d_contact >= 0.0, "d_contact = %g N s/m is invalid: expected >= 0", p->d_contact);
    CHECK(p->engage_length >= 0.0, "engage_length = %g m is invalid: expected >= 0", p->engage_length);
    CHECK(p->exit_thinning >= 0.0, "exit_thinning = %g m is invalid: expected >= 0", p->exit_thinning);
    CHECK(p->gap_thinning >= 0.0, "gap_thinning = %g m is invalid: expected >= 0", p->gap_thinning);
    CHECK(p->wear_holes >= 0.0, "wear_holes = %g is invalid: expected >= 0", p->wear_holes);
    CHECK(p->wear_cfrp >= 0.0, "wear_cfrp = %g 1/hole is invalid: expected >= 0", p->wear_cfrp);
    CHECK(p->wear_ti >= 0.0, "wear_ti = %g 1/hole is invalid: expected >= 0", p->wear_ti);
    CHECK(p->wear_al >= 0.0, "wear_al = %g 1/hole is invalid: expected >= 0", p->wear_al);
    CHECK(p->F_dyn_noise >= 0.0, "F_dyn_noise = %g N is invalid: expected >= 0", p->F_dyn_noise);
    CHECK(p->h_internal > 0.0 && p->h_internal <= 1e-3,
          "h_internal = %g s is invalid: expected 0 < h_internal <= 1e-3", p->h_internal);
    return 0;
}

/* ---------------------------------------------------------------- geometry */

void drill_build(Stack *s, const DrillParams *p)
{
    int k;
    double z = p->surface;
    s->n = p->n_layers;
    for (k = 0; k < s->n; k++) {
        int m = p->material[k];
        double preset = m == 1 ? p->kc_cfrp : m == 2 ? p->kc_ti : p->kc_al;
        double wear = m == 1 ? p->wear_cfrp : m == 2 ? p->wear_ti : p->wear_al;
        if (k > 0) z += p->gap[k];
        s->top[k] = z;
        z += p->thickness[k];
        s->bot[k] = z;
        s->material[k] = m;
        s->kc[k] = (p->kc[k] > 0.0 ? p->kc[k] : preset) * (1.0 + wear * p->wear_holes);
        s->descent[k] = m == 2 ? p->ti_descent : 0.0;
    }
    for (k = 0; k < s->n; k++) {
        if (k == s->n - 1) s->thin[k] = p->exit_thinning;
        else s->thin[k] = p->gap[k + 1] > 0.0 ? p->gap_thinning : 0.0;
    }
    s->L = p->engage_length;
    s->k = p->k_contact;
    s->d = p->d_contact;
    s->ripple_ratio = p->ripple_ratio;
    s->ripple_phase = p->ripple_phase;
}

/* kc_eff(c) = sum_k phi_k(c) * f_k(c) * kc_k * |[c-L, c] ∩ [top_k, bot_k]| / L
 *   phi_k: thinning of a free lower face (linear fall over the last thin_k, 0 past bot_k)
 *   f_k  : slow descent in Ti, exp(-descent * depth in layer) */
double drill_kc_eff(const Stack *s, double c)
{
    double sum = 0.0;
    int k;
    for (k = 0; k < s->n; k++) {
        double top = s->top[k], bot = s->bot[k], w, phi = 1.0;
        if (c <= top) break;                /* layers below are not reached yet */
        if (s->thin[k] > 0.0) {
            double r = bot - c;
            if (r <= 0.0) continue;         /* broken through: no thrust from this layer */
            if (r < s->thin[k]) phi = r / s->thin[k];
        }
        if (s->L > 0.0) {
            double a = c - s->L > top ? c - s->L : top;
            double b = c < bot ? c : bot;
            if (b <= a) continue;
            w = (b - a) / s->L;
        } else {
            if (c > bot) continue;
            w = 1.0;
        }
        if (s->descent[k] > 0.0) {
            double depth = (c < bot ? c : bot) - top;
            w *= exp(-s->descent[k] * depth);
        }
        sum += phi * w * s->kc[k];
    }
    return sum;
}

/* Contact force of the Maxwell element (spring k, damper d in parallel, in series with
 * the cutting "dashpot" dc/dt = k e n / kc_eff):  F = k e + d de/dt, de/dt = v - a e,
 * a = k n / kc_eff;  F >= 0 (the tool cannot pull the material). */
double drill_force_dc(const Stack *s, double kce, double c, double z, double v, double n_rps)
{
    double e = z - c, a, F;
    if (e <= 0.0) return 0.0;
    a = kce > 0.0 ? s->k * n_rps / kce : 0.0;
    F = s->k * e + s->d * (v - a * e);
    return F > 0.0 ? F : 0.0;
}

double drill_thrust(const Stack *s, const CutState *cut, double z, double v, double n_rps,
                    double *F_dc, double *F_r)
{
    double kce = drill_kc_eff(s, cut->c);
    *F_dc = drill_force_dc(s, kce, cut->c, z, v, n_rps);
    *F_r = s->ripple_ratio > 0.0 ? s->ripple_ratio * (*F_dc) * sin(cut->phi + s->ripple_phase) : 0.0;
    return kce;
}

/* Exact solution of de/dt = v - a e over h with v = (z1 - z0)/h (unconditionally stable,
 * also when a*h >> 1 at the start of the entry ramp). The cut front never moves back. */
double drill_advance_front(const Stack *s, double kce, double c, double z0, double z1, double h,
                           double n_rps)
{
    double e0 = z0 - c, e1, v, a;
    if (kce <= 0.0) return z1 > c ? z1 : c;       /* nothing engaged: free advance */
    if (e0 <= 0.0) return c;                      /* not in contact: nothing is cut */
    v = (z1 - z0) / h;
    a = s->k * n_rps / kce;
    if (a * h > 1e-9) {
        double E = exp(-a * h);
        e1 = e0 * E + v / a * (1.0 - E);
    } else {
        e1 = e0 + v * h;
    }
    if (e1 < 0.0) return c;                       /* retracted out of contact */
    {
        double c1 = z1 - e1;
        return c1 > c ? c1 : c;
    }
}

int drill_layer_at(const Stack *s, double z, int *material)
{
    int k;
    for (k = 0; k < s->n; k++) {
        if (z >= s->top[k] && z < s->bot[k]) {
            *material = s->material[k];
            return k + 1;
        }
    }
    *material = 0;
    return 0;
}
