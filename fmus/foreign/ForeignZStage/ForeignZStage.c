/* ForeignZStage: vertical linear-motor z stage (rigid), hand-written FMI 3.0 co-simulation
 * model. Equations: README.md beside this file. Interface units um, mA, mm/s; SI inside. */
#include <math.h>
#include <string.h>

#include "cut.h"
#include "stribeck.h"
#include "fglue.h"

enum {
    VR_IQ_CMD = 1, VR_SPINDLE_N = 2,
    VR_Z_MEAS = 10, VR_IQ_MEAS, VR_LOAD_CELL, VR_THRUST, VR_TIP_POS, VR_STAGE_VEL, VR_LAYER,
    VR_MATERIAL, VR_FRICTION,
    VR_MASS = 30, VR_KF, VR_G_ACC, VR_F_BAL, VR_TAU_CUR, VR_I_MAX, VR_I_NOISE, VR_F_COUL, VR_F_STAT,
    VR_V_STRB, VR_STRB_EXP, VR_C_VISC, VR_V_REG, VR_COG1, VR_COG_PITCH, VR_COG2, VR_COG2_PH,
    VR_ENC_RES, VR_Z_START, VR_H_SUB
};

const char FG_TOKEN[] = "{3c9d7e21-48b6-4f0a-b1e7-5a6c2d9f4b12}";
const unsigned FG_SEED_VR = VR_SEED;

const FgVar FG_VARS[] = {
    {"iq_cmd", VR_IQ_CMD, FG_F64, FG_INPUT, 0.0, 1, 0, "mA"},
    {"spindle_n", VR_SPINDLE_N, FG_F64, FG_INPUT, 3000.0, 1, 0, "rpm"},
    {"z_meas", VR_Z_MEAS, FG_F64, FG_OUTPUT, 0.0, 1, 0, "um"},
    {"iq_meas", VR_IQ_MEAS, FG_F64, FG_OUTPUT, 0.0, 1, 0, "mA"},
    {"load_cell", VR_LOAD_CELL, FG_F64, FG_OUTPUT, 0.0, 1, 0, "N"},
    {"thrust_force", VR_THRUST, FG_F64, FG_OUTPUT, 0.0, 1, 0, "N"},
    {"tip_pos", VR_TIP_POS, FG_F64, FG_OUTPUT, 0.0, 1, 0, "um"},
    {"stage_vel", VR_STAGE_VEL, FG_F64, FG_OUTPUT, 0.0, 1, 0, "mm/s"},
    {"layer_no", VR_LAYER, FG_F64, FG_OUTPUT, 0.0, 1, 0, ""},
    {"material_id", VR_MATERIAL, FG_F64, FG_OUTPUT, 0.0, 1, 0, ""},
    {"friction_force", VR_FRICTION, FG_F64, FG_OUTPUT, 0.0, 1, 0, "N"},
    {"mass", VR_MASS, FG_F64, FG_TUNABLE, 4.3, 0.1, 100.0, "kg"},
    {"Kf", VR_KF, FG_F64, FG_TUNABLE, 24.6, 0.1, 1000.0, "N/A"},
    {"g_acc", VR_G_ACC, FG_F64, FG_TUNABLE, 9.81, 0.0, 20.0, "m/s2"},
    {"F_bal", VR_F_BAL, FG_F64, FG_TUNABLE, 38.0, 0.0, 1000.0, "N"},
    {"tau_cur", VR_TAU_CUR, FG_F64, FG_TUNABLE, 0.12, 0.001, 100.0, "ms"},
    {"i_max", VR_I_MAX, FG_F64, FG_TUNABLE, 10.0, 0.01, 100.0, "A"},
    {"i_noise", VR_I_NOISE, FG_F64, FG_TUNABLE, 25.0, 0.0, 1000.0, "mA"},
    {"F_coul", VR_F_COUL, FG_F64, FG_TUNABLE, 6.0, 0.0, 100.0, "N"},
    {"F_stat", VR_F_STAT, FG_F64, FG_TUNABLE, 9.5, 0.0, 100.0, "N"},
    {"v_strb", VR_V_STRB, FG_F64, FG_TUNABLE, 3.0, 0.01, 100.0, "mm/s"},
    {"strb_exp", VR_STRB_EXP, FG_F64, FG_TUNABLE, 1.5, 0.5, 4.0, ""},
    {"c_visc", VR_C_VISC, FG_F64, FG_TUNABLE, 45.0, 0.0, 10000.0, "N.s/m"},
    {"v_reg", VR_V_REG, FG_F64, FG_TUNABLE, 0.001, 1e-5, 1.0, "mm/s"},
    {"cog1", VR_COG1, FG_F64, FG_TUNABLE, 1.2, 0.0, 100.0, "N"},
    {"cog_pitch", VR_COG_PITCH, FG_F64, FG_TUNABLE, 12.0, 0.1, 1000.0, "mm"},
    {"cog2", VR_COG2, FG_F64, FG_TUNABLE, 0.5, 0.0, 100.0, "N"},
    {"cog2_ph", VR_COG2_PH, FG_F64, FG_TUNABLE, 0.7, -10.0, 10.0, "rad"},
    {"enc_res", VR_ENC_RES, FG_F64, FG_PARAM, 10.0, 0.1, 1e5, "nm"},
    {"z_start", VR_Z_START, FG_F64, FG_PARAM, 0.0, -1e6, 1e6, "um"},
    {"h_sub", VR_H_SUB, FG_F64, FG_PARAM, 5.0, 0.1, 50.0, "us"},
    CUT_VARS(20.0, 300.0),
};
const int FG_NVARS = sizeof FG_VARS / sizeof FG_VARS[0];

typedef struct {
    CutStack st;
    double z, v, i, front;              /* m, m/s, A, m */
    double Ff, Fc;                      /* last friction and contact force [N] */
    double m, Kf, F_grav, imax, inoise, Fc0, dFs, vs_inv, sexp, c, vreg_inv;
    double cog1, k_cog, cog2, cog2_ph, q, lc_noise;
    double H_last, h, alpha;
    int nsub;
} ZS;

typedef char zs_fits[sizeof(ZS) <= FG_MODEL_BYTES ? 1 : -1];

static void derive(FgData *d) {
    ZS *s = (ZS *)d->model.bytes;
    const double *v = d->v;
    s->m = v[VR_MASS];
    s->Kf = v[VR_KF];
    s->F_grav = v[VR_MASS] * v[VR_G_ACC] - v[VR_F_BAL];   /* net weight along +z (down) */
    s->imax = v[VR_I_MAX];
    s->inoise = v[VR_I_NOISE] * 1e-3;
    s->Fc0 = v[VR_F_COUL];
    s->dFs = v[VR_F_STAT] - v[VR_F_COUL];
    s->vs_inv = 1.0 / (v[VR_V_STRB] * 1e-3);
    s->sexp = v[VR_STRB_EXP];
    s->c = v[VR_C_VISC];
    s->vreg_inv = 1.0 / (v[VR_V_REG] * 1e-3);
    s->cog1 = v[VR_COG1];
    s->k_cog = 2.0 * M_PI / (v[VR_COG_PITCH] * 1e-3);
    s->cog2 = v[VR_COG2];
    s->cog2_ph = v[VR_COG2_PH];
    s->q = v[VR_ENC_RES] * 1e-9;
    s->lc_noise = v[VR_LC_NOISE];
    cut_setup(&s->st, v);
    s->H_last = -1.0;
    d->dirty = 0;
}

int fg_model_check(FgInst *c, const char *fn) {
    const double *v = fg_data(c)->v;
    if (v[VR_F_STAT] < v[VR_F_COUL]) {
        fg_log_error(c, "%s: F_stat = %g N is invalid: expected >= F_coul = %g N (breakaway above "
                     "sliding friction)", fn, v[VR_F_STAT], v[VR_F_COUL]);
        return 0;
    }
    return cut_check(c, v, fn);
}

static double friction(const ZS *s, double w, double *slope) {
    return stribeck_friction(w, s->Fc0, s->dFs, s->vs_inv, s->sexp, s->vreg_inv, s->c, slope);
}

static void outputs(FgData *d) {
    ZS *s = (ZS *)d->model.bytes;
    double *v = d->v;
    double n_i = fg_gauss(d), n_f = fg_gauss(d);
    v[VR_Z_MEAS] = floor(s->z / s->q) * s->q * 1e6;
    v[VR_IQ_MEAS] = (s->i + s->inoise * n_i) * 1e3;
    v[VR_LOAD_CELL] = s->Fc + s->lc_noise * n_f;
    v[VR_THRUST] = s->Fc;
    v[VR_TIP_POS] = s->z * 1e6;
    v[VR_STAGE_VEL] = s->v * 1e3;
    v[VR_FRICTION] = s->Ff;
    cut_layer_at(&s->st, s->z, &v[VR_LAYER], &v[VR_MATERIAL]);
}

void fg_model_init(FgData *d) {
    ZS *s = (ZS *)d->model.bytes;
    memset(s, 0, sizeof *s);
    derive(d);
    s->z = d->v[VR_Z_START] * 1e-6;
    s->front = s->z;
    outputs(d);
}

void fg_model_step(FgData *d, double H) {
    ZS *s = (ZS *)d->model.bytes;
    if (d->dirty) derive(d);
    if (H != s->H_last) {
        s->nsub = (int)ceil(H / (d->v[VR_H_SUB] * 1e-6) - 1e-9);
        if (s->nsub < 1) s->nsub = 1;
        s->h = H / s->nsub;
        s->alpha = 1.0 - exp(-s->h / (d->v[VR_TAU_CUR] * 1e-3));
        s->H_last = H;
    }
    const double h = s->h;
    double i_cmd = d->v[VR_IQ_CMD] * 1e-3;
    if (i_cmd > s->imax) i_cmd = s->imax;
    if (i_cmd < -s->imax) i_cmd = -s->imax;
    const double n = fabs(d->v[VR_SPINDLE_N]) / 60.0;
    for (int k = 0; k < s->nsub; k++) {
        s->Fc = cut_step(&s->st, &s->front, s->z, s->v, n, h);
        double F_cog = s->cog1 * sin(s->k_cog * s->z) + s->cog2 * sin(2.0 * s->k_cog * s->z + s->cog2_ph);
        double slope;
        s->Ff = friction(s, s->v, &slope);
        if (slope < 0.0) slope = 0.0;
        s->v += h * (s->Kf * s->i + s->F_grav - F_cog - s->Fc - s->Ff) / (s->m + h * slope);
        s->z += h * s->v;
        s->i += s->alpha * (i_cmd - s->i);
    }
    outputs(d);
}
