/* Drill point and layered stack of the foreign2 plants: see f2stack.h. */
#include <math.h>

#include "f2stack.h"

static double clamp01(double s) { return s < 0.0 ? 0.0 : s > 1.0 ? 1.0 : s; }

void f2s_setup(F2Stack *st, const double *val) {
    const double mm = 1e-3;
    double z = val[F2S_SURFACE] * mm, kmin = 1e300;
    st->n = (int)val[F2S_NLAYERS];
    for (int k = 0; k < st->n; k++) {
        if (k > 0) z += val[F2S_GAP2 + k - 1] * mm;
        st->top[k] = z;
        z += val[F2S_T1 + k] * mm;
        st->bot[k] = z;
        int m = (int)val[F2S_MAT1 + k];
        st->mat[k] = m;
        double K = val[F2S_KL1 + k] > 0.0 ? val[F2S_KL1 + k]
                 : val[m == 1 ? F2S_K_CFRP : m == 2 ? F2S_K_TI : F2S_K_AL];
        double wear = val[m == 1 ? F2S_W_CFRP : m == 2 ? F2S_W_TI : F2S_W_AL];
        st->K[k] = K * (1.0 + 0.01 * wear * val[F2S_HOLES]);
        if (st->K[k] < kmin) kmin = st->K[k];
        st->free_below[k] = (k == st->n - 1) || val[F2S_GAP2 + k] > 0.0;
    }
    /* below 0.5 % of the softest layer the point is taken as cutting air: the front follows
       the tip instead of standing as an infinitely stiff sliver */
    st->K_air = 0.005 * kmin;
    st->inv_x = 1.0 / val[F2S_X_FEED];
    st->inv_Lpt = 1.0 / (val[F2S_L_PT] * mm);
    st->inv_tex = 1.0 / (val[F2S_T_EXIT] * mm);
    st->k_con = val[F2S_K_CON] * 1e6;
    st->d_con = val[F2S_D_CON];
}

int f2s_bad_layer(const double *val) {
    for (int k = 0; k < (int)val[F2S_NLAYERS]; k++)
        if (!(val[F2S_T1 + k] > 0.0)) return k + 1;
    return 0;
}

double f2s_k(const F2Stack *st, double c) {
    double K = 0.0;
    for (int k = 0; k < st->n; k++) {
        double in = clamp01((c - st->top[k]) * st->inv_Lpt);     /* share of the point below the top face */
        if (in == 0.0) continue;
        if (st->free_below[k]) {
            double r = clamp01((st->bot[k] - c) * st->inv_tex);
            in *= r * sqrt(r);
        } else {
            in -= clamp01((c - st->bot[k]) * st->inv_Lpt);       /* share already in the next layer */
        }
        K += st->K[k] * in;
    }
    return K;
}

double f2s_step(const F2Stack *st, double *c, double x, double v, double n, double h) {
    double K = f2s_k(st, *c);
    if (K <= st->K_air) {
        if (x > *c) *c = x;
        return 0.0;
    }
    double pen = x - *c;
    if (pen <= 0.0) return 0.0;
    double F = st->k_con * pen;
    double f_rev = n > 0.0 ? pow(F / K, st->inv_x) * 1e-3 : 0.0;     /* m per revolution */
    double c_new = *c + h * n * f_rev;
    if (c_new > x) c_new = x;
    double cdot = (c_new - *c) / h;
    *c = c_new;
    F += st->d_con * (v - cdot);
    return F > 0.0 ? F : 0.0;
}

void f2s_where(const F2Stack *st, double x, double *layer, double *material) {
    *layer = 0.0;
    *material = 0.0;
    for (int k = 0; k < st->n; k++)
        if (x >= st->top[k] && x < st->bot[k]) {
            *layer = k + 1;
            *material = st->mat[k];
            return;
        }
}
