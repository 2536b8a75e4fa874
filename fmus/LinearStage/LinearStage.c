/* LinearStage: Keio z-axis linear-motor stage (Yamamoto & Kakinuma) with drill and layered
 * workpiece.  Equations and solver: docs/plants.md.  Variables: LinearStage_vars.h
 * (generated from fmus/spec.py). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "drill.h"
#include "model_api.h"
#include "LinearStage_vars.h"

typedef struct {
    ModelVars v;        /* parameters, inputs, outputs (value-reference table offsets) */
    /* states */
    double z, vel, i_motor;
    CutState cut;
    Prng rng;
    /* derived */
    Stack stack;
    double F_fric;
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
    CHECK(v->M > 0.0, "M = %g kg is invalid: expected a moving mass > 0", v->M);
    CHECK(v->Kt > 0.0, "Kt = %g N/A is invalid: expected a thrust constant > 0", v->Kt);
    CHECK(v->g >= 0.0, "g = %g m/s2 is invalid: expected >= 0", v->g);
    CHECK(v->F_gc >= 0.0, "F_gc = %g N is invalid: expected >= 0", v->F_gc);
    CHECK(v->F_coulomb >= 0.0, "F_coulomb = %g N is invalid: expected >= 0", v->F_coulomb);
    CHECK(v->b_viscous >= 0.0, "b_viscous = %g N s/m is invalid: expected >= 0", v->b_viscous);
    CHECK(v->F_stribeck >= 0.0, "F_stribeck = %g N is invalid: expected >= 0", v->F_stribeck);
    CHECK(v->v_stribeck > 0.0, "v_stribeck = %g m/s is invalid: expected > 0", v->v_stribeck);
    CHECK(v->tau_i > 0.0, "tau_i = %g s is invalid: expected a current-loop time constant > 0", v->tau_i);
    CHECK(v->i_noise >= 0.0, "i_noise = %g A is invalid: expected >= 0", v->i_noise);
    CHECK(v->i_max > 0.0, "i_max = %g A is invalid: expected > 0", v->i_max);
    CHECK(v->enc_resolution > 0.0, "enc_resolution = %g m is invalid: expected > 0", v->enc_resolution);
    CHECK(v->F_cog >= 0.0, "F_cog = %g N is invalid: expected >= 0", v->F_cog);
    CHECK(v->cog_pitch > 0.0, "cog_pitch = %g m is invalid: expected > 0", v->cog_pitch);
    DRILL_PARAMS_FROM_VARS(&p, v);
    if (drill_validate(&p, msg, n)) return 1;
    /* stability of the fixed-step integration (explicit in the contact spring/dampers) */
    CHECK(v->k_contact * v->h_internal * v->h_internal / v->M < 0.5,
          "k_contact = %g N/m is too stiff for h_internal = %g s and M = %g kg: expected "
          "k_contact*h_internal^2/M < 0.5 (reduce h_internal)", v->k_contact, v->h_internal, v->M);
    CHECK(v->d_contact * v->h_internal / v->M < 0.5,
          "d_contact = %g N s/m is too large for h_internal = %g s: expected d_contact*h_internal/M < 0.5",
          v->d_contact, v->h_internal);
    CHECK(v->b_viscous * v->h_internal / v->M < 0.5,
          "b_viscous = %g N s/m is too large for h_internal = %g s: expected b_viscous*h_internal/M < 0.5",
          v->b_viscous, v->h_internal);
    return 0;
}

static void compute_outputs(ModelData *d, double F_dc, double F_r)
{
    ModelVars *v = &d->v;
    int mat;
    double g1 = prng_gauss(&d->rng), g2 = prng_gauss(&d->rng);
    v->z_enc = floor(d->z / v->enc_resolution) * v->enc_resolution;
    v->i_meas = d->i_motor + v->i_noise * g1;
    v->F_thrust_true = F_dc + F_r;
    v->F_ripple_true = F_r;
    v->F_dyn = v->F_thrust_true + v->F_dyn_noise * g2;
    v->F_friction_true = d->F_fric;
    v->layer = (double)drill_layer_at(&d->stack, d->z, &mat);
    v->material = (double)mat;
    v->z_tool_true = d->z;
    v->v_true = d->vel;
}

static double thrust(const ModelData *d, double n_rps, double *F_dc, double *F_r)
{
    return drill_thrust(&d->stack, &d->cut, d->z, d->vel, n_rps, F_dc, F_r);
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
    d->z = d->v.z0;
    d->vel = 0.0;
    d->i_motor = 0.0;
    d->cut.c = d->v.z0; /* a start inside the stack means: pre-drilled to z0 */
    d->cut.phi = 0.0;
    d->F_fric = 0.0;
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
    const double F_bias = v->M * v->g - v->F_gc;
    const double inv_M = 1.0 / v->M;
    const double k_cog = 2.0 * M_PI / v->cog_pitch;
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
            double F_ext, acc, v_new, z_old = d->z;
            kce = thrust(d, n_rps, &F_dc, &F_r);
            /* M a = Kt i + M g - F_gc - F_thrust + F_cog sin(2 pi z / p) - F_fric */
            F_ext = v->Kt * d->i_motor + F_bias - (F_dc + F_r);
            if (v->F_cog != 0.0) F_ext += v->F_cog * sin(k_cog * d->z);
            d->F_fric = stick_slip_friction(F_ext, d->vel, v->F_coulomb, v->F_stribeck, v->v_stribeck,
                                            v->b_viscous);
            acc = (F_ext - d->F_fric) * inv_M;      /* 0 while stuck */
            /* semi-implicit (symplectic) Euler; a velocity sign change sticks at 0 */
            v_new = d->vel + acc * h;
            if (d->vel != 0.0 && v_new * d->vel < 0.0) v_new = 0.0;
            d->vel = v_new;
            d->z += v_new * h;
            /* current loop: exact first-order lag over the sub-step */
            d->i_motor += (i_cmd - d->i_motor) * exp_i;
            /* cutting: advance the cut front, orbital phase */
            d->cut.c = drill_advance_front(&d->stack, kce, d->cut.c, z_old, d->z, h, n_rps);
            d->cut.phi += w_orb * h;
        }
        if (d->cut.phi > 2.0 * M_PI || d->cut.phi < -2.0 * M_PI) d->cut.phi = fmod(d->cut.phi, 2.0 * M_PI);
    }
    if (!isfinite(d->z) || !isfinite(d->vel) || !isfinite(d->i_motor) || !isfinite(d->cut.c)) {
        snprintf(msg, n, "state became non-finite (z = %g m, v = %g m/s, i_motor = %g A, cut front = %g m)",
                 d->z, d->vel, d->i_motor, d->cut.c);
        return 1;
    }
    thrust(d, n_rps, &F_dc, &F_r);
    compute_outputs(d, F_dc, F_r);
    return 0;
}
