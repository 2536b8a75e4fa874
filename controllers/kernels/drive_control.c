/* One sample of the Keio / ball-screw drive blocks, in C (issue #15):
 *
 *   trajectory_step      drillcosim.controllers.trajectory.FeedTrajectory.step
 *   position_step        drillcosim.controllers.position_control.PositionController.step
 *   force_control_step   drillcosim.controllers.force_control.ThrustForceController.step
 *   keio_observer_step   drillcosim.controllers.keio_observer.CuttingForceObserver.step
 *
 * The same arithmetic as the Python steps, operation for operation (compiled with
 * -ffp-contract=off: no fused multiply-adds), so both give the same doubles; the Python
 * stays the readable reference and documents the equations (tests/test_speed_kernels.py
 * compares them). Python's min(a, b) returns a unless b < a, max(a, b) a unless b > a:
 * MIN / MAX below keep that order (it matters for NaN only). Every struct holds doubles
 * only (flags and modes as 0.0 / 1.0 ...), mirrored field for field by
 * controllers/kernels/structs.py. Signature of every step: (state, t, u, y).
 */
#include <math.h>

#define MIN(a, b) ((b) < (a) ? (b) : (a))
#define MAX(a, b) ((b) > (a) ? (b) : (a))
#define MAX_RIPPLE 8
#define MAX_PASSES 8      /* trajectory.py MAX_PASSES */

/* ---------------------------------------------------------------- shared pieces */

/* drillcosim.controllers.trajectory.profile_step */
static void profile_step(double z, double v, double z_target, double v_max, double a_max,
                         double dt, double v_next, double *z_o, double *v_o, double *a_o)
{
    double d = z_target - z;
    double sgn = d >= 0.0 ? 1.0 : -1.0;
    double dist = fabs(d);
    double v_tgt = sgn * MIN(v_max, sqrt(v_next * v_next + 2.0 * a_max * dist));
    double a = MAX(-a_max, MIN(a_max, (v_tgt - v) / dt));
    double v_new = v + a * dt;
    double z_new = z + v * dt + 0.5 * a * dt * dt;
    if (v_next == 0.0 && ((z_target - z_new) * sgn <= 0.0
                          || (dist <= a_max * dt * dt && fabs(v_new) <= 2.0 * a_max * dt))) {
        *z_o = z_target;
        *v_o = 0.0;
        *a_o = MAX(-a_max, MIN(a_max, -v / dt));
        return;
    }
    *z_o = z_new;
    *v_o = v_new;
    *a_o = a;
}

/* drillcosim.controllers.position_force: a static force that changes with the stroke (a spring-type
 * gravity compensator), F0 + sum_k c[k-1] (z - z0)^k by Horner in the Python order; with no
 * terms F0 itself, so a drive without one computes exactly what it did before */
#define POSITION_FORCE_TERMS 6          /* controllers/position_force.py MAX_TERMS */

static double static_force(double F0, double n, double z0, const double *c, double z)
{
    if (n == 0.0)
        return F0;
    int m = (int)n;
    double y = z - z0;
    double acc = c[m - 1];
    for (int k = m - 2; k >= 0; k--)
        acc = acc * y + c[k];
    return F0 + acc * y;
}

/* drillcosim.controllers.position_control.RobustAcceleration */
typedef struct {
    double M, Kt, g_dob, g_vel, i_max, F_bias, dt0;
    double has_prev, z_prev, t_prev, v, a, F_dis, i, i_unsat, dt;
    double has_poles, dt_poles, av, ad, F_bias_z;
    double pf_n, pf_z0, pf[POSITION_FORCE_TERMS];
} Robust;

static double robust_measure(Robust *c, double t, double z)
{
    c->F_bias_z = static_force(c->F_bias, c->pf_n, c->pf_z0, c->pf, z);
    if (c->has_prev == 0.0) {
        c->has_prev = 1.0;
        c->z_prev = z;
        c->t_prev = t;
        return c->v;
    }
    double dt = t > c->t_prev ? t - c->t_prev : c->dt0;
    c->dt = dt;
    if (c->has_poles == 0.0 || dt != c->dt_poles) {
        c->has_poles = 1.0;
        c->dt_poles = dt;
        c->av = exp(-c->g_vel * dt);
        c->ad = exp(-c->g_dob * dt);
    }
    double av = c->av, ad = c->ad;
    double v_new = av * c->v + (1.0 - av) * (z - c->z_prev) / dt;
    c->a = (v_new - c->v) / dt;
    c->v = v_new;
    double raw = c->Kt * c->i + c->F_bias_z - c->M * c->a;
    c->F_dis = ad * c->F_dis + (1.0 - ad) * raw;
    c->z_prev = z;
    c->t_prev = t;
    return c->v;
}

static double robust_current(Robust *c, double a_ref)
{
    double i = (c->M * a_ref - c->F_bias_z + c->F_dis) / c->Kt;
    c->i_unsat = i;
    c->i = MAX(-c->i_max, MIN(c->i_max, i));
    return c->i;
}

/* drillcosim.controllers.position_control.pd_feedforward */
static double pd_feedforward(double Kp, double Kv, double z_ref, double z, double v_ff,
                             double v_hat, double a_ff)
{
    return a_ff + Kv * (Kp * (z_ref - z) + v_ff - v_hat);
}

/* drillcosim.controllers.friction.FrictionModel.force and .position_ripple */
typedef struct {
    double coulomb, viscous, stribeck, v_stribeck, exponent, v_eps;
    double n_ripple, ripple[3 * MAX_RIPPLE];      /* rows [k, a_sin, a_cos] */
} Friction;

static double friction_force(const Friction *f, double v)
{
    double s;
    if (v > f->v_eps)
        s = 1.0;
    else if (v < -f->v_eps)
        s = -1.0;
    else
        s = v / f->v_eps;
    double F = f->coulomb * s + f->viscous * v;
    if (f->stribeck != 0.0)
        F += f->stribeck * s * exp(-pow(fabs(v) / f->v_stribeck, f->exponent));
    return F;
}

static double friction_ripple(const Friction *f, double p)
{
    double F = 0.0;
    int n = (int)f->n_ripple;
    for (int j = 0; j < n; j++) {
        const double *r = f->ripple + 3 * j;
        F += r[1] * sin(r[0] * p) + r[2] * cos(r[0] * p);
    }
    return F;
}

/* ---------------------------------------------------------------- FeedTrajectory */

enum { PHASE_WAIT, PHASE_APPROACH, PHASE_FEED, PHASE_RETRACT, PHASE_DONE };

typedef struct {
    double z_start, z_approach_end, v_approach, feed_rate, z_end, v_retract, a_max, t_start, dt;
    double z, v, phase, has_t_prev, t_prev, cmd, retract;
    double n_pass, pass_z[MAX_PASSES], pass_feed[MAX_PASSES];
} Trajectory;

/* trajectory.py FeedTrajectory._feed: an air pass's feed below its end, else the command or the setting */
static double trajectory_feed(const Trajectory *s, double cmd, double z)
{
    for (int i = 0; i < (int)s->n_pass; i++)
        if (z < s->pass_z[i])
            return s->pass_feed[i];
    return cmd > 0.0 ? cmd : s->feed_rate;
}

/* u: feed_rate_cmd, retract; y: z_ref, v_ref, a_ref, phase */
void trajectory_step(Trajectory *s, double t, const double *u, double *y)
{
    double cmd = s->cmd;
    int retract = s->retract != 0.0, lift = s->z_approach_end < s->z_start;
    s->cmd = u[0];
    s->retract = u[1] > 0.5 ? 1.0 : 0.0;
    double dt = (s->has_t_prev == 0.0 || t <= s->t_prev) ? s->dt : t - s->t_prev;
    s->has_t_prev = 1.0;
    s->t_prev = t;
    double z = s->z, v = s->v;
    int ph = (int)s->phase;
    if (ph == PHASE_WAIT && t >= s->t_start - 1e-12)
        ph = PHASE_APPROACH;
    if (ph == PHASE_APPROACH && (lift ? z <= s->z_approach_end && v == 0.0 : z >= s->z_approach_end))
        ph = PHASE_FEED;
    if (ph == PHASE_FEED && z >= s->z_end)
        ph = PHASE_RETRACT;
    if (retract && (ph == PHASE_APPROACH || ph == PHASE_FEED))
        ph = PHASE_RETRACT;
    if (ph == PHASE_RETRACT && z <= s->z_start && v == 0.0)
        ph = PHASE_DONE;
    double z1, v1, a;
    if (ph == PHASE_APPROACH)
        profile_step(z, v, s->z_approach_end, s->v_approach, s->a_max, dt,
                     lift ? 0.0 : trajectory_feed(s, cmd, s->z_approach_end), &z1, &v1, &a);
    else if (ph == PHASE_FEED)
        profile_step(z, v, s->z_end, trajectory_feed(s, cmd, z), s->a_max, dt, 0.0, &z1, &v1, &a);
    else if (ph == PHASE_RETRACT)
        profile_step(z, v, s->z_start, s->v_retract, s->a_max, dt, 0.0, &z1, &v1, &a);
    else {
        z1 = z;
        v1 = 0.0;
        a = 0.0;
    }
    s->z = z1;
    s->v = v1;
    s->phase = ph;
    y[0] = z;
    y[1] = v;
    y[2] = a;
    y[3] = ph;
}

/* ---------------------------------------------------------------- PositionController */

typedef struct {
    double Kp, Kv;
    Robust core;
} Position;

/* u: z_ref, v_ref, a_ref, z; y: i_ref, v_hat, F_dis_hat, a_cmd, saturated */
void position_step(Position *s, double t, const double *u, double *y)
{
    Robust *c = &s->core;
    double z = u[3];
    double v_hat = robust_measure(c, t, z);
    double a_cmd = pd_feedforward(s->Kp, s->Kv, u[0], z, u[1], v_hat, u[2]);
    double i = robust_current(c, a_cmd);
    y[0] = i;
    y[1] = v_hat;
    y[2] = c->F_dis;
    y[3] = a_cmd;
    y[4] = fabs(c->i_unsat) > c->i_max ? 1.0 : 0.0;
}

/* ---------------------------------------------------------------- ThrustForceController */

enum { MODE_APPROACH, MODE_FORCE, MODE_RETRACT };

typedef struct {
    double Kp, Kv, Kf, force_control, F_contact, t_confirm, z_contact_min;
    double exit_min_depth, F_exit_ratio, t_exit_confirm, z_limit;
    double z_retract, v_retract, a_retract, v_max, tau_switch;
    double mode, a_last, a_off, t_switch, has_above, t_above, has_below, t_below;
    double z_contact, zr, vr, i_abs_max, sat_any;
    Robust core;
} Force;

/* drillcosim.controllers.force_control.held_for: 1 once `cond` has held for `duration` s */
static int held_for(int cond, double t, double *has_since, double *since, double duration)
{
    if (!cond) {
        *has_since = 0.0;
        return 0;
    }
    if (*has_since == 0.0) {
        *has_since = 1.0;
        *since = t;
    }
    return t - *since >= duration - 1e-12;
}

static void force_switch(Force *s, double t, int mode, double z, double v_hat)
{
    s->mode = mode;
    s->t_switch = t;
    if (mode == MODE_FORCE)
        s->z_contact = z;
    else if (mode == MODE_RETRACT) {
        s->zr = z;
        s->vr = v_hat;
    }
}

/* u: z_ref, v_ref, a_ref, z, F_cmd, F_thrust_hat; y: i_ref, v_hat, mode, a_cmd, F_dis_hat,
 * saturated, F_cmd_out, z_contact, i_ref_max, saturated_any */
void force_control_step(Force *s, double t, const double *u, double *y)
{
    double z_ref = u[0], v_ff = u[1], a_ff = u[2], z = u[3], F_cmd = u[4], F_hat = u[5];
    Robust *c = &s->core;
    double v_hat = robust_measure(c, t, z);
    int prev_mode = (int)s->mode;
    if (prev_mode == MODE_APPROACH && s->force_control != 0.0) {
        if (held_for(F_hat > s->F_contact && z >= s->z_contact_min, t, &s->has_above, &s->t_above,
                     s->t_confirm))
            force_switch(s, t, MODE_FORCE, z, v_hat);
    } else if (prev_mode == MODE_FORCE) {
        if (z >= s->z_limit)
            force_switch(s, t, MODE_RETRACT, z, v_hat);
        else if (held_for(z - s->z_contact >= s->exit_min_depth && F_hat < s->F_exit_ratio * F_cmd,
                          t, &s->has_below, &s->t_below, s->t_exit_confirm))
            force_switch(s, t, MODE_RETRACT, z, v_hat);
    }
    int mode = (int)s->mode;
    double a_raw;
    if (mode == MODE_APPROACH)
        a_raw = pd_feedforward(s->Kp, s->Kv, z_ref, z, v_ff, v_hat, a_ff);
    else if (mode == MODE_FORCE) {
        a_raw = s->Kf * (F_cmd - F_hat) / c->M;
        if (s->v_max < INFINITY)
            a_raw = MIN(a_raw, s->Kv * (s->v_max - v_hat));
    } else {
        double zr = s->zr, vr = s->vr, z1, v1, ar;
        profile_step(zr, vr, s->z_retract, s->v_retract, s->a_retract, c->dt, 0.0, &z1, &v1, &ar);
        a_raw = pd_feedforward(s->Kp, s->Kv, zr, z, vr, v_hat, ar);
        s->zr = z1;
        s->vr = v1;
    }
    if (mode != prev_mode)
        s->a_off = s->a_last - a_raw;
    double a_cmd = a_raw;
    if (s->a_off != 0.0) {
        double decay = exp(-(t - s->t_switch) / s->tau_switch);
        a_cmd += s->a_off * decay;
        if (decay < 1e-6)
            s->a_off = 0.0;
    }
    s->a_last = a_cmd;
    double i = robust_current(c, a_cmd);
    double sat = fabs(c->i_unsat) > c->i_max ? 1.0 : 0.0;
    s->i_abs_max = MAX(s->i_abs_max, fabs(i));
    s->sat_any = MAX(s->sat_any, sat);
    y[0] = i;
    y[1] = v_hat;
    y[2] = mode;
    y[3] = a_cmd;
    y[4] = c->F_dis;
    y[5] = sat;
    y[6] = mode == MODE_FORCE ? F_cmd : 0.0;
    y[7] = s->z_contact;
    y[8] = s->i_abs_max;
    y[9] = s->sat_any;
}

/* ---------------------------------------------------------------- CuttingForceObserver */

typedef struct {
    double Kt_n, M_n, F_grav_comp, a, b, Ts, v_stick, F_static, held, has_ripple;
    double first, z_prev, v_prev, i_prev, F_dis, v_lp;
    Friction fr;
    double pf_n, pf_z0, pf[POSITION_FORCE_TERMS];
} KeioObserver;

/* u: i_ref, z; y: F_thrust_hat, F_ref, v_hat */
void keio_observer_step(KeioObserver *s, double t, const double *u, double *y)
{
    (void)t;
    double i_in = u[0], z = u[1];
    double Ts = s->Ts;
    if (s->first != 0.0) {
        s->first = 0.0;
        s->z_prev = z;
        s->i_prev = i_in;
        s->F_dis = 0.0;
    }
    double i_last = s->held != 0.0 ? i_in : s->i_prev;
    double v = (z - s->z_prev) / Ts;
    double F_grav = static_force(s->F_grav_comp, s->pf_n, s->pf_z0, s->pf, z);
    double d = s->Kt_n * i_last - s->M_n * (v - s->v_prev) / Ts + F_grav;
    double rip = s->has_ripple != 0.0 ? friction_ripple(&s->fr, z) : 0.0;
    double fric;
    if (-s->v_stick <= v && v <= s->v_stick) {
        double f_st = d - rip, Fs = s->F_static;
        fric = rip + ((-Fs <= f_st && f_st <= Fs) ? f_st : (f_st > 0 ? Fs : -Fs));
    } else {
        fric = friction_force(&s->fr, v) + rip;
    }
    s->F_dis = s->a * s->F_dis + s->b * (d - fric);
    s->v_lp = s->a * s->v_lp + s->b * v;
    s->z_prev = z;
    s->v_prev = v;
    s->i_prev = i_in;
    double fric_lp = friction_force(&s->fr, s->v_lp) + rip;
    y[0] = s->F_dis;
    y[1] = s->Kt_n * i_in - fric_lp + F_grav;
    y[2] = s->v_lp;
}

/* ---------------------------------------------------------------- VelocitySegments */

#define MAX_PHASES 96

typedef struct {
    double n, z_end;
    double ph[6 * MAX_PHASES];    /* rows [t0, duration, a, v0, z0, segment] */
} Segments;

/* drillcosim.controllers.friction.VelocitySegments.step: no inputs; y: z_ref, v_ref, a_ref, segment */
void segments_step(Segments *s, double t, const double *u, double *y)
{
    (void)u;
    int n = (int)s->n;
    for (int j = 0; j < n; j++) {
        const double *p = s->ph + 6 * j;
        double t0 = p[0], dur = p[1], a = p[2], v0 = p[3], z0 = p[4];
        if (t0 <= t && t < t0 + dur) {
            double q = t - t0;
            y[0] = z0 + v0 * q + 0.5 * a * q * q;
            y[1] = v0 + a * q;
            y[2] = a;
            y[3] = p[5];
            return;
        }
        if (t < t0) {
            y[0] = z0;
            y[1] = 0.0;
            y[2] = 0.0;
            y[3] = 0.0;
            return;
        }
    }
    y[0] = s->z_end;
    y[1] = 0.0;
    y[2] = 0.0;
    y[3] = 0.0;
}
