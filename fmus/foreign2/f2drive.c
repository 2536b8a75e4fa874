/* Feed-drive parts of the foreign2 plants: see f2drive.h. */
#include <math.h>

#include "f2drive.h"

void f2d_derive(F2Drive *d, const double *val, unsigned a, unsigned f, double vs_si, double vreg_si) {
    d->imax = val[a + 1];
    d->ibias = val[a + 2] * 1e-3;
    d->igain = 1.0 + val[a + 3] * 0.01;
    d->inoise = val[a + 4] * 1e-3;
    d->Fc = val[f];
    d->dFs = val[f + 1] - val[f];
    d->vs = val[f + 2] * vs_si;
    d->sexp = val[f + 3];
    d->visc = val[f + 4];
    d->vreg = val[f + 5] * vreg_si;
    d->lc = val[F2S_DYN_NOISE];
    f2s_setup(&d->st, val);
    d->H_last = -1.0;
}

int f2d_check(F2Inst *c, const char *fn, unsigned f) {
    const double *p = c->s.val;
    if (p[f + 1] < p[f]) {
        const F2Var *vc = f2_find(f), *vs = f2_find(f + 1);
        f2_log(c, 1, "%s: %s = %g %s is refused: expected >= %s = %g %s (breakaway at or above sliding "
               "friction)", fn, vs->name, p[f + 1], vs->unit, vc->name, p[f], vc->unit);
        return 0;
    }
    int bad = f2s_bad_layer(p);
    if (bad) {
        f2_log(c, 1, "%s: t%d = %g mm is refused: expected > 0 for a layer in use (n_layers = %d)", fn, bad,
               p[F2S_T1 + bad - 1], (int)p[F2S_NLAYERS]);
        return 0;
    }
    return 1;
}

void f2d_substeps(F2Drive *d, double H, double h_sub, double tau_i) {
    if (H == d->H_last) return;
    d->nsub = (int)ceil(H / (h_sub * 1e-6) - 1e-9);
    if (d->nsub < 1) d->nsub = 1;
    d->h = H / d->nsub;
    d->alpha = 1.0 - exp(-d->h / (tau_i * 1e-3));
    d->H_last = H;
}

double f2d_limit(const F2Drive *d, double i_cmd) {
    return i_cmd > d->imax ? d->imax : i_cmd < -d->imax ? -d->imax : i_cmd;
}

void f2d_current(F2Drive *d, double i_cmd) { d->i += d->alpha * (i_cmd - d->i); }

double f2d_sensed(const F2Drive *d, double noise) { return d->igain * d->i + d->ibias + d->inoise * noise; }

double f2d_friction(const F2Drive *d, double v, double *slope) {
    const double vs = d->vs, a = d->sexp, vr = d->vreg, dFs = d->dFs;
    double u = (v < 0 ? -v : v) / vs;
    double e = exp(-pow(u, a));
    double g = d->Fc + dFs * e;
    double q = sqrt(v * v + vr * vr);
    double s = v / q;
    double dg = u > 0.0 ? -dFs * e * a * pow(u, a - 1.0) / vs * (v < 0 ? -1.0 : 1.0) : 0.0;
    *slope = dg * s + g * vr * vr / (q * q * q) + d->visc;
    if (*slope < 0.0) *slope = 0.0;
    return g * s + d->visc * v;
}
