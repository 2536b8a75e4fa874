/* One sample of drillcosim.controllers.fang_observer.AdaptiveThrustObserver, in C (issue #15).
 *
 * The same arithmetic as the Python step (AdaptiveThrustObserver._step_python), in the
 * same order, so that both give the same doubles (compiled with -ffp-contract=off:
 * no fused multiply-adds). The Python side owns the struct (ctypes), sets the constants
 * once, and calls fang_observer_step() once per sample; equations and choices are
 * documented in controllers/fang_observer.py.
 */
#include <math.h>

#define FANG_MAX_RIPPLE 8
#define FANG_MAX_HARMONICS 4                 /* fang_observer.py MAX_HARMONICS */
#define FANG_NH (2 * FANG_MAX_HARMONICS)
#define TWO_PI 6.283185307179586
#define PI 3.141592653589793
#define FANG_STILL_RAD_S 0.05                /* fang_observer.py STILL_RAD_S */
#define FANG_SCALE_RESTART 0.25              /* fang_observer.py SCALE_RESTART */
#define FANG_SCALE_RESTART_FLOORS 2.0        /* fang_observer.py SCALE_RESTART_FLOORS */

typedef struct {
    /* constants: discretised observer (row-major Phi), forgetting, friction */
    double Phi[9], Bu[3], By[3], Bg[3];
    double fdecay, fgain, avel, kf, Ts, K_Tn, y_theta, sx;
    double coulomb, viscous, stribeck, v_stribeck, v_eps, offset, stribeck_exponent;
    double ripple[3 * FANG_MAX_RIPPLE];   /* rows [k, a_sin, a_cos] */
    double f_orb_setting;                 /* Hz, < 0: from the input */
    int n_ripple, use_theta, meas_theta;
    int k_theta, k_orbital;               /* index of theta / orbital speed in u, -1: absent */
    /* state */
    int first;
    double t0, phase, x[3], Y[6], th[2], Si[3], th_prev, w_enc;
    /* harmonics > 1: theta [S_1, C_1, .., S_H, C_H], Y (3 x 2H), Gamma^-1 (2H x 2H), row-major */
    int harmonics;
    double th_h[FANG_NH], Y_h[3 * FANG_NH], Si_h[FANG_NH * FANG_NH];
    /* gain restart at a commanded orbit-speed change (_restart_gain): relative change, the
     * orbital frequency [Hz] Gamma was last rescaled for */
    double gain_restart, f_gain;
    /* ripple regressor scaled by the previous sample's F_dc_hat [N] (_ripple_scale): on,
     * samples above 3 floors before the switch, switched, samples above so far, floor [N],
     * the previous F_dc_hat [N]; the cut's thrust F_prev - F_air low-passed [N], its lag per
     * sample (fang_observer.py SCALE_TAU_S) */
    int scale_thrust, n_switch, switched, n_above;
    double scale_floor, F_prev, F_level, fscale;
    double rs_gain;                       /* the highest scale since Gamma^-1 was last resized (_ripple_scale) */
    /* theta held until F_dc_hat first rises adapt_from [N] above its air level F_air [N]
     * for more than n_adapt samples in a row (_ripple_held): adapting yet, samples held so
     * far, samples in a row above so far */
    int adapt, n_held;
    double adapt_from, F_air;
    int n_rise, n_adapt;
    /* the motion's start (START_S): samples feeding in a row, how many of them are the start,
     * the air level's lag over it per sample */
    int n_feed, n_start;
    double fstart;
} FangObserver;

static double friction(const FangObserver *o, double v)
{
    double s = v > o->v_eps ? 1.0 : (v < -o->v_eps ? -1.0 : v / o->v_eps);
    double f = o->coulomb * s + o->viscous * v;
    if (o->stribeck != 0.0)      /* pow, as Python's ** calls it: the same double for any exponent */
        f += o->stribeck * s * exp(-pow(fabs(v) / o->v_stribeck, o->stribeck_exponent));
    return f;
}

static double position_ripple(const FangObserver *o, double p)
{
    double f = 0.0;
    for (int j = 0; j < o->n_ripple; j++) {
        const double *r = o->ripple + 3 * j;
        f += r[1] * sin(r[0] * p) + r[2] * cos(r[0] * p);
    }
    return f;
}

/* the identified cogging torque [N m] at motor angle theta, fed into the model (_cogging) */
static double cogging(const FangObserver *o, double theta)
{
    return o->use_theta ? position_ripple(o, theta) : 0.0;
}

/* Gamma^-1 (one harmonic's and H harmonics') times q (_scale_gain_inverse) */
static void scale_gain_inverse(FangObserver *o, double q)
{
    int n = 2 * o->harmonics;
    for (int i = 0; i < 3; i++)
        o->Si[i] *= q;
    for (int i = 0; i < n * n; i++)
        o->Si_h[i] *= q;
}

/* Gamma^-1 rescaled to the new orbit's regressor at a commanded orbit-speed change
 * (_restart_gain): by (f_new / f_old)^2, when both are > 0 */
static void restart_gain(FangObserver *o, double f_orb)
{
    if (o->f_gain > 0.0 && f_orb > 0.0) {
        double r = f_orb / o->f_gain;
        scale_gain_inverse(o, r * r);
    }
    o->f_gain = f_orb;
}

/* the sample's inputs and orbital angle phi(t) (_sample): starts the state on the first
 * sample, advances the phase */
static void sample(FangObserver *o, double t, const double *u, double *i_m_, double *y_, double *theta_,
                   double *phi_, double *f_orb_)
{
    double i_m = u[0], x_meas = u[1];
    double theta = o->k_theta >= 0 ? u[o->k_theta] : 0.0;
    double orbital_rpm = o->k_orbital >= 0 ? u[o->k_orbital] : 0.0;
    double y = o->meas_theta ? o->y_theta * theta : o->sx * x_meas;
    double Ts = o->Ts;
    int from_input = o->f_orb_setting < 0.0;
    double f_orb = from_input ? orbital_rpm / 60.0 : o->f_orb_setting;
    if (o->first) {
        o->first = 0;
        o->x[0] = y; o->x[1] = 0.0; o->x[2] = o->K_Tn * i_m;
        o->th_prev = theta;
        o->phase = from_input ? TWO_PI * f_orb * (t - o->t0) : 0.0;
    }
    double phi;
    if (from_input) {
        if (o->gain_restart > 0.0 && fabs(f_orb - o->f_gain) > o->gain_restart * o->f_gain)
            restart_gain(o, f_orb);
        phi = o->phase;
        o->phase = phi + TWO_PI * f_orb * Ts;
    } else {
        phi = TWO_PI * f_orb * t;
    }
    *i_m_ = i_m;
    *y_ = y;
    *theta_ = theta;
    *phi_ = phi;
    *f_orb_ = f_orb;
}

/* the outputs at t (_outputs) from the updated state and the ripple torque tau_r */
static void outputs(FangObserver *o, double xn1, double xn2, double theta, double th0, double th1,
                    double tau_r, double rs, double cog, double *out)
{
    double kf = o->kf, w_f, Ts = o->Ts;
    if (o->use_theta) {
        double av = o->avel;
        o->w_enc = av * o->w_enc + (1.0 - av) * (theta - o->th_prev) / Ts;
        o->th_prev = theta;
        w_f = o->w_enc;
    } else {
        w_f = xn1;
    }
    double tau_f = friction(o, w_f) + o->offset;
    double F_dc = kf * (xn2 - tau_f);
    o->F_prev = F_dc;
    double F_r = kf * tau_r;
    out[0] = F_dc;
    out[1] = F_r;
    out[2] = xn2 + cog + tau_r;
    out[3] = F_dc + F_r;
    out[4] = kf * rs * hypot(th0, th1);
    out[5] = atan2(th1, th0);
    out[6] = xn1;
}

/* eq. 8's ripple parameters -> the share at scale rs (_to_share) */
static void to_share(FangObserver *o, double rs)
{
    int n = 2 * o->harmonics;
    o->switched = 1;
    o->rs_gain = rs;
    for (int i = 0; i < 2; i++)
        o->th[i] = o->th[i] / rs;
    for (int i = 0; i < n; i++)
        o->th_h[i] = o->th_h[i] / rs;
    for (int i = 0; i < 6; i++)
        o->Y[i] = o->Y[i] * rs;
    for (int i = 0; i < 3 * n; i++)
        o->Y_h[i] = o->Y_h[i] * rs;
    scale_gain_inverse(o, rs * rs);
}

/* the factor on the ripple regressor (_ripple_scale): 1, or after 1/lambda above 3 floors
 * max(F_level, floor) / floor, F_level: F_prev - F_air through a lag */
static double ripple_scale(FangObserver *o)
{
    if (!o->scale_thrust)
        return 1.0;
    double fl = o->scale_floor, a = o->fscale;
    /* the cut's thrust: less the air level, low-passed (F_dc_hat's noise moved the scale) */
    double F = o->F_level = a * o->F_level + (1.0 - a) * (o->F_prev - o->F_air);
    double rs = (F > fl ? F : fl) / fl;
    if (o->switched) {
        if (rs < (1.0 - FANG_SCALE_RESTART) * o->rs_gain && o->rs_gain - rs > FANG_SCALE_RESTART_FLOORS) {
            double q = rs / o->rs_gain;
            scale_gain_inverse(o, q * q);
            o->rs_gain = rs;
        } else if (rs > o->rs_gain) {
            o->rs_gain = rs;
        }
        return rs;
    }
    o->n_above = F > 3.0 * fl ? o->n_above + 1 : 0;
    if (o->n_above < o->n_switch)
        return 1.0;
    to_share(o, rs);
    return rs;
}

/* 1 while theta is held (_ripple_held): until F_prev stays adapt_from above F_air for more
 * than n_adapt samples while the motor feeds (turns forward) past its start (n_start samples,
 * over which F_air follows F_prev through fstart), F_air held while it retreats,
 * F_dc_hat's mean while held (exponential over 1/lambda) */
static int ripple_held(FangObserver *o)
{
    if (o->adapt)
        return 0;
    double F = o->F_prev;
    if (o->n_held < 2) {
        o->F_air = F;
    } else {
        double w = o->use_theta ? o->w_enc : o->x[1];
        int feeding = w > FANG_STILL_RAD_S;
        o->n_feed = feeding ? o->n_feed + 1 : 0;
        if (o->n_feed > 0 && o->n_feed <= o->n_start) {   /* the motion's start: the feed's air level */
            double a = o->fstart;
            o->F_air = a * o->F_air + (1.0 - a) * F;
            o->n_rise = 0;
        } else {
            o->n_rise = feeding && F - o->F_air > o->adapt_from ? o->n_rise + 1 : 0;
            if (o->n_rise > o->n_adapt) {
                o->adapt = 1;
                return 0;
            }
            if (w >= -FANG_STILL_RAD_S) {    /* a retreat's thrust is no air level (_ripple_held) */
                double a = o->fdecay;
                o->F_air = a * o->F_air + (1.0 - a) * F;
            }
        }
    }
    o->n_held = o->n_held + 1;
    return 1;
}

static void regressor(double phi, int harmonics, double *reg)
{
    for (int h = 1; h <= harmonics; h++) {
        reg[2 * h - 2] = sin((double)h * phi);
        reg[2 * h - 1] = cos((double)h * phi);
    }
}

/* z = S^-1 c, S symmetric positive definite n x n (_spd_solve: Cholesky, two triangular solves) */
static void spd_solve(const double *S, const double *c, int n, double *z)
{
    double L[FANG_NH * FANG_NH], w[FANG_NH];
    for (int i = 0; i < n; i++)
        for (int j = 0; j <= i; j++) {
            double v = S[i * n + j];
            for (int k = 0; k < j; k++)
                v -= L[i * n + k] * L[j * n + k];
            L[i * n + j] = i == j ? sqrt(v) : v / L[j * n + j];
        }
    for (int i = 0; i < n; i++) {
        double v = c[i];
        for (int k = 0; k < i; k++)
            v -= L[i * n + k] * w[k];
        w[i] = v / L[i * n + i];
    }
    for (int i = n - 1; i >= 0; i--) {
        double v = w[i];
        for (int k = i + 1; k < n; k++)
            v -= L[k * n + i] * z[k];
        z[i] = v / L[i * n + i];
    }
}

/* one sample with H > 1 orbital harmonics (_step_python_harmonics) */
static void step_harmonics(FangObserver *o, double i_m, double y, double theta, double phi, double f_orb,
                           double *out)
{
    int n = 2 * o->harmonics;
    double Ts = o->Ts, reg[FANG_NH], z[FANG_NH], d[FANG_NH], Yn[3 * FANG_NH], xn[3];
    double phim = phi + PI * f_orb * Ts;
    double rs = ripple_scale(o);
    regressor(phim, o->harmonics, reg);
    for (int j = 0; j < n; j++)
        reg[j] = rs * reg[j];
    double x0 = o->x[0], x1 = o->x[1], x2 = o->x[2];
    const double *Y = o->Y_h, *P = o->Phi, *G = o->Bg, *U = o->Bu, *B = o->By;
    double e = y - x0;
    spd_solve(o->Si_h, Y, n, z);
    for (int j = 0; j < n; j++)
        d[j] = Ts * z[j] * e;
    if (ripple_held(o))
        for (int j = 0; j < n; j++)
            d[j] = 0.0;
    for (int r = 0; r < 3; r++)
        for (int j = 0; j < n; j++)
            Yn[r * n + j] = P[3 * r] * Y[j] + P[3 * r + 1] * Y[n + j] + P[3 * r + 2] * Y[2 * n + j] + G[r] * reg[j];
    double cog = cogging(o, theta);
    double tr = 0.0;
    for (int j = 0; j < n; j++)
        tr += o->th_h[j] * reg[j];
    tr += cog;
    for (int r = 0; r < 3; r++) {
        double v = P[3 * r] * x0 + P[3 * r + 1] * x1 + P[3 * r + 2] * x2 + U[r] * i_m + B[r] * y + G[r] * tr;
        for (int j = 0; j < n; j++)
            v += Yn[r * n + j] * d[j];
        xn[r] = v;
    }
    for (int r = 0; r < 3; r++)
        o->x[r] = xn[r];
    for (int j = 0; j < 3 * n; j++)
        o->Y_h[j] = Yn[j];
    for (int j = 0; j < n; j++)
        o->th_h[j] += d[j];
    double a = o->fdecay, b = o->fgain;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++)
            o->Si_h[i * n + j] = a * o->Si_h[i * n + j] + b * Yn[i] * Yn[j];
    regressor(phi, o->harmonics, reg);
    double tau_r = 0.0;
    for (int j = 0; j < n; j++)
        tau_r += o->th_h[j] * reg[j];
    outputs(o, xn[1], xn[2], theta, o->th_h[0], o->th_h[1], rs * tau_r, rs, cog, out);
}

/* u: the block's inputs in port order (i_m, x[, theta][, orbital_speed]);
 * out: F_dc_hat, F_ripple_hat, tau_d_hat, F_cut_hat, ripple_amplitude_hat,
 * ripple_phase_hat, w_hat */
void fang_observer_step(FangObserver *o, double t, const double *u, double *out)
{
    double i_m, y, theta, phi, f_orb, Ts = o->Ts;
    sample(o, t, u, &i_m, &y, &theta, &phi, &f_orb);
    if (o->harmonics > 1) {
        step_harmonics(o, i_m, y, theta, phi, f_orb, out);
        return;
    }
    double phim = phi + PI * f_orb * Ts;
    double rs = ripple_scale(o);
    double sm = rs * sin(phim), cm = rs * cos(phim);

    double x0 = o->x[0], x1 = o->x[1], x2 = o->x[2];
    double th0 = o->th[0], th1 = o->th[1];
    double s00 = o->Si[0], s01 = o->Si[1], s11 = o->Si[2];
    double det = s00 * s11 - s01 * s01;
    double g00 = s11 / det, g01 = -s01 / det, g11 = s00 / det;
    double e = y - x0;
    const double *Y = o->Y;
    double cy0 = Y[0], cy1 = Y[1];
    double d0 = Ts * (g00 * cy0 + g01 * cy1) * e;
    double d1 = Ts * (g01 * cy0 + g11 * cy1) * e;
    if (ripple_held(o)) {
        d0 = 0.0;
        d1 = 0.0;
    }

    const double *P = o->Phi, *G = o->Bg, *U = o->Bu, *B = o->By;
    double n0 = P[0] * Y[0] + P[1] * Y[2] + P[2] * Y[4] + G[0] * sm;
    double n1 = P[0] * Y[1] + P[1] * Y[3] + P[2] * Y[5] + G[0] * cm;
    double n2 = P[3] * Y[0] + P[4] * Y[2] + P[5] * Y[4] + G[1] * sm;
    double n3 = P[3] * Y[1] + P[4] * Y[3] + P[5] * Y[5] + G[1] * cm;
    double n4 = P[6] * Y[0] + P[7] * Y[2] + P[8] * Y[4] + G[2] * sm;
    double n5 = P[6] * Y[1] + P[7] * Y[3] + P[8] * Y[5] + G[2] * cm;
    double cog = cogging(o, theta);
    double tr = th0 * sm + th1 * cm + cog;   /* ripple and cogging torque (_cogging) */
    double xn0 = P[0] * x0 + P[1] * x1 + P[2] * x2 + U[0] * i_m + B[0] * y + G[0] * tr + n0 * d0 + n1 * d1;
    double xn1 = P[3] * x0 + P[4] * x1 + P[5] * x2 + U[1] * i_m + B[1] * y + G[1] * tr + n2 * d0 + n3 * d1;
    double xn2 = P[6] * x0 + P[7] * x1 + P[8] * x2 + U[2] * i_m + B[2] * y + G[2] * tr + n4 * d0 + n5 * d1;
    o->x[0] = xn0; o->x[1] = xn1; o->x[2] = xn2;
    o->Y[0] = n0; o->Y[1] = n1; o->Y[2] = n2; o->Y[3] = n3; o->Y[4] = n4; o->Y[5] = n5;
    th0 += d0;
    th1 += d1;
    o->th[0] = th0; o->th[1] = th1;
    double a = o->fdecay, b = o->fgain;
    o->Si[0] = a * s00 + b * n0 * n0;
    o->Si[1] = a * s01 + b * n0 * n1;
    o->Si[2] = a * s11 + b * n1 * n1;

    double s = sin(phi), c = cos(phi);
    outputs(o, xn1, xn2, theta, th0, th1, rs * (th0 * s + th1 * c), rs, cog, out);
}
