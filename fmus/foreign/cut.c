/* Drill and layered stack of the foreign plants: see cut.h. */
#include <math.h>

#include "cut.h"

static double smoothstep(double s) {
    if (s <= 0.0) return 0.0;
    if (s >= 1.0) return 1.0;
    return s * s * (3.0 - 2.0 * s);
}

void cut_setup(CutStack *st, const double *v) {
    const double mm = 1e-3;
    int n = (int)v[VR_NLAYERS];
    double top = v[VR_SURFACE] * mm;
    double kmin = INFINITY;
    st->n = n;
    for (int k = 0; k < n; k++) {
        if (k > 0) top += v[VR_GAP2 + k - 1] * mm;
        st->top[k] = top;
        st->bot[k] = top + v[VR_T1 + k] * mm;
        top = st->bot[k];
        int m = (int)v[VR_MAT1 + k];
        st->mat[k] = m;
        double preset = m == 1 ? v[VR_K_CFRP] : m == 2 ? v[VR_K_TI] : v[VR_K_AL];
        double wear = m == 1 ? v[VR_WEAR_CFRP] : m == 2 ? v[VR_WEAR_TI] : v[VR_WEAR_AL];
        double K = v[VR_KC1 + k] > 0.0 ? v[VR_KC1 + k] : preset;
        st->K[k] = K * (1.0 + 0.01 * wear * v[VR_WEAR_HOLES]);
        if (st->K[k] < kmin) kmin = st->K[k];
    }
    for (int k = 0; k < n; k++)
        st->free_below[k] = (k == n - 1) || v[VR_GAP2 + k] > 0.0;   /* gap{k+2} is VR_GAP2 + k */
    /* 1 % of the softest layer: the last 10 % of exit_t of a push-out, the first ~6 % of the
     * engagement ramp are air (a jump of ~1 % of the thrust, instead of a stiff front) */
    st->K_floor = 0.01 * kmin;
    st->inv_exp = 1.0 / v[VR_FEED_EXP];
    st->inv_L = 1.0 / (v[VR_ENGAGE] * mm);
    st->inv_rex = 1.0 / (v[VR_EXIT_T] * mm);
    st->kw = v[VR_K_CONTACT] * 1e6;
    st->dw = v[VR_D_CONTACT];
}

int cut_check(FgInst *c, const double *v, const char *fn) {
    int n = (int)v[VR_NLAYERS];
    static const char *names[4] = {"t1", "t2", "t3", "t4"};
    for (int k = 0; k < n; k++) {
        if (!(v[VR_T1 + k] > 0.0)) {
            fg_log_error(c, "%s: %s = %g mm is invalid: expected > 0 for a used layer (n_layers = %d)",
                         fn, names[k], v[VR_T1 + k], n);
            return 0;
        }
    }
    return 1;
}

double cut_keff(const CutStack *st, double c) {
    double K = 0.0;
    for (int k = 0; k < st->n; k++) {
        double w = smoothstep((c - st->top[k]) * st->inv_L);
        if (w == 0.0) continue;
        if (st->free_below[k]) {
            double r = (st->bot[k] - c) * st->inv_rex;
            w *= r <= 0.0 ? 0.0 : r >= 1.0 ? 1.0 : r * r;
        } else {
            w -= smoothstep((c - st->bot[k]) * st->inv_L);
        }
        K += st->K[k] * w;
    }
    return K;
}

double cut_step(const CutStack *st, double *front, double x, double v, double n, double h) {
    double K = cut_keff(st, *front);
    if (K <= st->K_floor) {         /* air, gap, or through: nothing ahead of the tip */
        if (x > *front) *front = x;
        return 0.0;
    }
    double e = x - *front;
    if (e <= 0.0) return 0.0;       /* tip retracted from the front */
    double F_el = st->kw * e;
    double rate = n > 0.0 ? n * 1e-3 * pow(F_el / K, st->inv_exp) : 0.0;   /* mm/rev -> m/rev */
    double c_new = *front + h * rate;
    if (c_new > x) c_new = x;       /* the front never passes the tip */
    double cdot = (c_new - *front) / h;
    *front = c_new;
    double F = F_el + st->dw * (v - cdot);
    return F > 0.0 ? F : 0.0;
}

void cut_layer_at(const CutStack *st, double x, double *layer, double *material) {
    *layer = 0.0;
    *material = 0.0;
    for (int k = 0; k < st->n; k++) {
        if (x >= st->top[k] && x < st->bot[k]) {
            *layer = k + 1;
            *material = st->mat[k];
            return;
        }
    }
}
