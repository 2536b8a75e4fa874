/* BallScrewDrive: servo motor + ball screw feed drive of the orbital drilling end-effector
 * (Fang et al. 2015, eqs. 1-8, Table 1) with drill and layered workpiece.
 * Equations and solver: docs/plants.md.  Variables: BallScrewDrive_vars.h (generated from
 * fmus/spec.py). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "drill.h"
#include "model_api.h"
#include "BallScrewDrive_vars.h"

typedef struct {
    ModelVars v;        /* parameters, inputs, outputs (value-reference table offsets) */
    /* states */
    double theta, w, i_motor;
    CutState cut;
    Prng rng;
    /* derived */
    Stack stack;
    double tau_fric;
} ModelData;

MODEL_INFO_DEFINE(ModelData);

void model_set_defaults(void *data)
{
    MODEL_SET_START_VALUES(data);
}

#define CHECK(cond, ...) do { if (!(cond)) { snprintf(msg, n, __VA_ARGS__); return 1; } } while (0)

int model_validate(const void *data, char *msg, size_t n)
{
    const ModelVars *v = &((const ModelData *)data)->v;
    DrillParams p;
    CHECK(v->J_e > 0.0, "J_e = %g kg m2 is invalid: expected an equivalent inertia > 0", v->J_e);
    CHECK(v->K_T > 0.0, "K_T = %g N m/A is invalid: expected a torque constant > 0", v->K_T);
    CHECK(v->K_pitch > 0.0, "K_pitch = %g m/rad is invalid: expected a ball-screw lead > 0", v->K_pitch);
    CHECK(v->eta > 0.0 && v->eta <= 1.0, "eta = %g is invalid: expected an efficiency 0 < eta <= 1", v->eta);
    CHECK(v->tau_coulomb >= 0.0, "tau_coulomb = %g N m is invalid: expected >= 0", v->tau_coulomb);
    CHECK(v->tau_stribeck >= 0.0, "tau_stribeck = %g N m is invalid: expected >= 0", v->tau_stribeck);
    CHECK(v->w_stribeck > 0.0, "w_stribeck = %g rad/s is invalid: expected > 0", v->w_stribeck);
    CHECK(v->D_viscous >= 0.0, "D_viscous = %g N m s/rad is invalid: expected >= 0", v->D_viscous);
    CHECK(v->tau_cog >= 0.0, "tau_cog = %g N m is invalid: expected >= 0", v->tau_cog);
    CHECK(v->tau_i > 0.0, "tau_i = %g s is invalid: expected a current-loop time constant > 0", v->tau_i);
    CHECK(v->i_noise >= 0.0, "i_noise = %g A is invalid: expected >= 0", v->i_noise);
    CHECK(v->i_max > 0.0, "i_max = %g A is invalid: expected > 0", v->i_max);
    CHECK(v->enc_resolution > 0.0, "enc_resolution = %g m is invalid: expected > 0", v->enc_resolution);
    CHECK(v->motor_enc_counts >= 1, "motor_enc_counts = %d is invalid: expected >= 1 count per revolution",
          v->motor_enc_counts);
    DRILL_PARAMS_FROM_VARS(&p, v);
    if (drill_validate(&p, msg, n)) return 1;
    {
        /* stability of the fixed-step integration; table-side equivalent mass eta*J_e/K_pitch^2 */
        double m_eq = v->eta * v->J_e / (v->K_pitch * v->K_pitch);
        CHECK(v->k_contact * v->h_internal * v->h_internal / m_eq < 0.5,
              "k_contact = %g N/m is too stiff for h_internal = %g s and the equivalent mass %g kg: "
              "expected k_contact*h_internal^2/(eta*J_e/K_pitch^2) < 0.5 (reduce h_internal)",
              v->k_contact, v->h_internal, m_eq);
        CHECK(v->d_contact * v->h_internal / m_eq < 0.5,
              "d_contact = %g N s/m is too large for h_internal = %g s: expected d_contact*h_internal*K_pitch^2/(eta*J_e) < 0.5",
              v->d_contact, v->h_internal);
        CHECK(v->D_viscous * v->h_internal / v->J_e < 0.5,
              "D_viscous = %g N m s/rad is too large for h_internal = %g s: expected D_viscous*h_internal/J_e < 0.5",
              v->D_viscous, v->h_internal);
    }
    return 0;
}

static void compute_outputs(ModelData *d, double F_dc, double F_r)
{
    ModelVars *v = &d->v;
    int mat;
    double g1 = prng_gauss(&d->rng), g2 = prng_gauss(&d->rng);
    double x = v->x0 + v->K_pitch * d->theta;
    double res_th = 2.0 * M_PI / (double)v->motor_enc_counts;
    v->x_enc = floor(x / v->enc_resolution) * v->enc_resolution;
    v->theta_enc = floor(d->theta / res_th) * res_th;
    v->i_meas = d->i_motor + v->i_noise * g1;
    v->F_thrust_true = F_dc + F_r;
    v->F_ripple_true = F_r;
    v->F_dyn = v->F_thrust_true + v->F_dyn_noise * g2;
    v->tau_friction_true = d->tau_fric;
    v->layer = (double)drill_layer_at(&d->stack, x, &mat);
    v->material = (double)mat;
    v->x_tool_true = x;
    v->w_m_true = d->w;
}

static double thrust(const ModelData *d, double n_rps, double *F_dc, double *F_r)
{
    return drill_thrust(&d->stack, &d->cut, d->v.x0 + d->v.K_pitch * d->theta, d->v.K_pitch * d->w,
                        n_rps, F_dc, F_r);
}

static void rebuild(ModelData *d)
{
    DrillParams p;
    DRILL_PARAMS_FROM_VARS(&p, &d->v);
    drill_build(&d->stack, &p);
}

void model_initialize(void *data, double start_time)
{
    ModelData *d = (ModelData *)data;
    double F_dc, F_r;
    (void)start_time;
    rebuild(d);
    d->theta = 0.0;
    d->w = 0.0;
    d->i_motor = 0.0;
    d->cut.c = d->v.x0; /* a start inside the stack means: pre-drilled to x0 */
    d->cut.phi = 0.0;
    d->tau_fric = 0.0;
    prng_seed(&d->rng, (int64_t)d->v.seed);
    thrust(d, fabs(d->v.spindle_speed) / 60.0, &F_dc, &F_r);
    compute_outputs(d, F_dc, F_r);
}

int model_do_step(void *data, double t, double H, char *msg, size_t n)
{
    ModelData *d = (ModelData *)data;
    ModelVars *v = &d->v;
    const double n_rps = fabs(v->spindle_speed) / 60.0;
    const double w_orb = 2.0 * M_PI * v->orbital_speed / 60.0;
    const double inv_J = 1.0 / v->J_e;
    const double ext_gain = v->K_pitch / v->eta;   /* tau_ext = F K_pitch / eta (eq. 6) */
    double i_cmd = v->i_ref, F_dc = 0.0, F_r = 0.0, kce, h;
    const int nsub = substeps(H, v->h_internal, &h);
    const double exp_i = 1.0 - exp(-h / v->tau_i);
    int k;
    (void)t;
    if (!isfinite(i_cmd)) {
        snprintf(msg, n, "input i_ref = %g is not finite", v->i_ref);
        return 1;
    }
    if (i_cmd > v->i_max) i_cmd = v->i_max;
    if (i_cmd < -v->i_max) i_cmd = -v->i_max;
    rebuild(d);
    if (H > 0.0) {
        for (k = 0; k < nsub; k++) {
            double tau_ext, acc, w_new, x_old = v->x0 + v->K_pitch * d->theta, x_new;
            kce = thrust(d, n_rps, &F_dc, &F_r);
            /* J_e dw/dt = K_T i - tau_d, tau_d = F K_pitch/eta + tau_cog sin(h theta) + tau_f(w)
             * (Fang eqs. 1-4, 6) */
            tau_ext = v->K_T * d->i_motor - (F_dc + F_r) * ext_gain;
            if (v->tau_cog != 0.0) tau_ext -= v->tau_cog * sin(v->cog_harmonic * d->theta);
            d->tau_fric = stick_slip_friction(tau_ext, d->w, v->tau_coulomb, v->tau_stribeck, v->w_stribeck,
                                              v->D_viscous);
            acc = (tau_ext - d->tau_fric) * inv_J;  /* 0 while stuck */
            w_new = d->w + acc * h;
            if (d->w != 0.0 && w_new * d->w < 0.0) w_new = 0.0;
            d->w = w_new;
            d->theta += w_new * h;
            d->i_motor += (i_cmd - d->i_motor) * exp_i;
            x_new = v->x0 + v->K_pitch * d->theta;
            d->cut.c = drill_advance_front(&d->stack, kce, d->cut.c, x_old, x_new, h, n_rps);
            d->cut.phi += w_orb * h;
        }
        if (d->cut.phi > 2.0 * M_PI || d->cut.phi < -2.0 * M_PI) d->cut.phi = fmod(d->cut.phi, 2.0 * M_PI);
    }
    if (!isfinite(d->theta) || !isfinite(d->w) || !isfinite(d->i_motor) || !isfinite(d->cut.c)) {
        snprintf(msg, n, "state became non-finite (theta = %g rad, w = %g rad/s, i_motor = %g A, cut front = %g m)",
                 d->theta, d->w, d->i_motor, d->cut.c);
        return 1;
    }
    thrust(d, n_rps, &F_dc, &F_r);
    compute_outputs(d, F_dc, F_r);
    return 0;
}
