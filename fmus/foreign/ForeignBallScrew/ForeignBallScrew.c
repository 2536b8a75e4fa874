/* ForeignBallScrew: orbital-drilling feed drive as a two-mass system (motor + screw spring
 * + table), hand-written FMI 3.0 co-simulation model. Equations: README.md beside this file.
 * Units at the interface are the machine's (mA, mm, deg, rpm, Hz); SI inside. */
#include <math.h>
#include <string.h>

#include "cut.h"
#include "stribeck.h"
#include "fglue.h"

/* Interface units: machine units (mA, mm, deg) by default. -DFOREIGN_SI_INTERFACE builds the
   SI twin (A, m, rad at the interface, the same physics and noise), with which a test shows
   that the identification through plant roles does not depend on the FMU's units
   (fmus/foreign/build.py: build_si_twin). */
#ifdef FOREIGN_SI_INTERFACE
#define TO_MA 1.0
#define TO_MM 1.0
#define TO_DEG 1.0
#else
#define TO_MA 1e3
#define TO_MM 1e3
#define TO_DEG (180.0 / M_PI)
#endif

enum {
    /* inputs */
    VR_IQ_REF = 1, VR_SPINDLE_N = 2, VR_ORBIT_F = 3,
    /* outputs */
    VR_IQ_MEAS = 10, VR_SCALE_POS, VR_MOTOR_ANGLE, VR_LOAD_CELL, VR_THRUST, VR_RIPPLE, VR_TIP_POS,
    VR_TABLE_VEL, VR_MOTOR_VEL, VR_FRICTION, VR_LAYER, VR_MATERIAL,
    /* drive parameters */
    VR_JM = 30, VR_M_TABLE, VR_LEAD, VR_K_SCREW, VR_D_SCREW, VR_KT, VR_TAU_CUR, VR_I_MAX, VR_I_NOISE,
    VR_T_COUL, VR_T_STAT, VR_W_STRB, VR_STRB_EXP, VR_B_VISC, VR_W_REG,
    VR_RIPA, VR_RIPA_N, VR_RIPA_PH, VR_RIPB, VR_RIPB_N, VR_RIPB_PH,
    VR_ENC_COUNTS, VR_SCALE_RES, VR_X_START, VR_H_SUB,
    /* orbital ripple (after the shared stack block 60..90) */
    VR_ORB_R1 = 91, VR_ORB_R2, VR_ORB_PH2
};

const char FG_TOKEN[] = "{f0e1b5c2-7d3a-4e1b-9a5c-3b2d1f6e8a01}";
const unsigned FG_SEED_VR = VR_SEED;

const FgVar FG_VARS[] = {
    {"iq_ref", VR_IQ_REF, FG_F64, FG_INPUT, 0.0, 1, 0, "mA"},
    {"spindle_n", VR_SPINDLE_N, FG_F64, FG_INPUT, 2000.0, 1, 0, "rpm"},
    {"orbit_f", VR_ORBIT_F, FG_F64, FG_INPUT, 2.0, 1, 0, "Hz"},
    {"iq_meas", VR_IQ_MEAS, FG_F64, FG_OUTPUT, 0.0, 1, 0, "mA"},
    {"scale_pos", VR_SCALE_POS, FG_F64, FG_OUTPUT, 0.0, 1, 0, "mm"},
    {"motor_angle", VR_MOTOR_ANGLE, FG_F64, FG_OUTPUT, 0.0, 1, 0, "deg"},
    {"load_cell", VR_LOAD_CELL, FG_F64, FG_OUTPUT, 0.0, 1, 0, "N"},
    {"thrust_force", VR_THRUST, FG_F64, FG_OUTPUT, 0.0, 1, 0, "N"},
    {"thrust_ripple", VR_RIPPLE, FG_F64, FG_OUTPUT, 0.0, 1, 0, "N"},
    {"tip_pos", VR_TIP_POS, FG_F64, FG_OUTPUT, 0.0, 1, 0, "mm"},
    {"table_vel", VR_TABLE_VEL, FG_F64, FG_OUTPUT, 0.0, 1, 0, "mm/s"},
    {"motor_vel", VR_MOTOR_VEL, FG_F64, FG_OUTPUT, 0.0, 1, 0, "rpm"},
    {"friction_torque", VR_FRICTION, FG_F64, FG_OUTPUT, 0.0, 1, 0, "N.m"},
    {"layer_no", VR_LAYER, FG_F64, FG_OUTPUT, 0.0, 1, 0, ""},
    {"material_id", VR_MATERIAL, FG_F64, FG_OUTPUT, 0.0, 1, 0, ""},
    {"Jm", VR_JM, FG_F64, FG_TUNABLE, 2.0e-4, 1e-6, 1.0, "kg.m2"},
    {"m_table", VR_M_TABLE, FG_F64, FG_TUNABLE, 40.0, 0.1, 1000.0, "kg"},
    {"lead", VR_LEAD, FG_F64, FG_PARAM, 4.0, 0.5, 50.0, "mm"},
    {"k_screw", VR_K_SCREW, FG_F64, FG_TUNABLE, 130.0, 1.0, 2000.0, "N/um"},
    {"d_screw", VR_D_SCREW, FG_F64, FG_TUNABLE, 4000.0, 0.0, 1e6, "N.s/m"},
    {"Kt", VR_KT, FG_F64, FG_TUNABLE, 0.87, 0.01, 20.0, "N.m/A"},
    {"tau_cur", VR_TAU_CUR, FG_F64, FG_TUNABLE, 0.3, 0.001, 100.0, "ms"},
    {"i_max", VR_I_MAX, FG_F64, FG_TUNABLE, 8.0, 0.01, 100.0, "A"},
    {"i_noise", VR_I_NOISE, FG_F64, FG_TUNABLE, 15.0, 0.0, 1000.0, "mA"},
    {"T_coul", VR_T_COUL, FG_F64, FG_TUNABLE, 0.045, 0.0, 10.0, "N.m"},
    {"T_stat", VR_T_STAT, FG_F64, FG_TUNABLE, 0.075, 0.0, 10.0, "N.m"},
    {"w_strb", VR_W_STRB, FG_F64, FG_TUNABLE, 0.6, 0.01, 100.0, "rad/s"},
    {"strb_exp", VR_STRB_EXP, FG_F64, FG_TUNABLE, 1.5, 0.5, 4.0, ""},
    {"b_visc", VR_B_VISC, FG_F64, FG_TUNABLE, 8.0e-4, 0.0, 1.0, "N.m.s/rad"},
    {"w_reg", VR_W_REG, FG_F64, FG_TUNABLE, 0.002, 1e-5, 1.0, "rad/s"},
    {"ripA", VR_RIPA, FG_F64, FG_TUNABLE, 0.006, 0.0, 1.0, "N.m"},
    {"ripA_n", VR_RIPA_N, FG_F64, FG_TUNABLE, 4.0, 0.0, 100.0, ""},
    {"ripA_ph", VR_RIPA_PH, FG_F64, FG_TUNABLE, 0.0, -10.0, 10.0, "rad"},
    {"ripB", VR_RIPB, FG_F64, FG_TUNABLE, 0.003, 0.0, 1.0, "N.m"},
    {"ripB_n", VR_RIPB_N, FG_F64, FG_TUNABLE, 9.0, 0.0, 100.0, ""},
    {"ripB_ph", VR_RIPB_PH, FG_F64, FG_TUNABLE, 1.2, -10.0, 10.0, "rad"},
    {"enc_counts", VR_ENC_COUNTS, FG_I32, FG_PARAM, 65536, 4, 1 << 30, ""},
    {"scale_res", VR_SCALE_RES, FG_F64, FG_PARAM, 1.0, 0.001, 1000.0, "um"},
    {"x_start", VR_X_START, FG_F64, FG_PARAM, 0.0, -1000.0, 1000.0, "mm"},
    {"h_sub", VR_H_SUB, FG_F64, FG_PARAM, 5.0, 0.1, 50.0, "us"},
    CUT_VARS(20.0, 3000.0),
    {"orb_r1", VR_ORB_R1, FG_F64, FG_TUNABLE, 0.12, 0.0, 1.0, ""},
    {"orb_r2", VR_ORB_R2, FG_F64, FG_TUNABLE, 0.04, 0.0, 1.0, ""},
    {"orb_ph2", VR_ORB_PH2, FG_F64, FG_TUNABLE, 0.9, -10.0, 10.0, "rad"},
};
const int FG_NVARS = sizeof FG_VARS / sizeof FG_VARS[0];

/* the model's states and derived constants (plain data, in FgData.model) */
typedef struct {
    CutStack st;
    double th, w, x, v, i, front, phi;  /* rad, rad/s, m, m/s, A, m, rad */
    double tf, Fc, Fr;                  /* last friction torque, contact force, ripple [N m, N, N] */
    /* derived from parameters */
    double p, J, m, k, d, Kt, imax, inoise, Tc, dTs, ws_inv, sexp, b, wreg_inv;
    double rA, nA, phA, rB, nB, phB, qa, qx, x0, r1, r2, ph2, lc_noise;
    double H_last, h, alpha;            /* sub-step for the last communication step */
    int nsub;
} BS;

typedef char bs_fits[sizeof(BS) <= FG_MODEL_BYTES ? 1 : -1];

static void derive(FgData *d) {
    BS *s = (BS *)d->model.bytes;
    const double *v = d->v;
    s->p = v[VR_LEAD] * 1e-3 / (2.0 * M_PI);
    s->J = v[VR_JM];
    s->m = v[VR_M_TABLE];
    s->k = v[VR_K_SCREW] * 1e6;
    s->d = v[VR_D_SCREW];
    s->Kt = v[VR_KT];
    s->imax = v[VR_I_MAX];
    s->inoise = v[VR_I_NOISE] * 1e-3;
    s->Tc = v[VR_T_COUL];
    s->dTs = v[VR_T_STAT] - v[VR_T_COUL];
    s->ws_inv = 1.0 / v[VR_W_STRB];
    s->sexp = v[VR_STRB_EXP];
    s->b = v[VR_B_VISC];
    s->wreg_inv = 1.0 / v[VR_W_REG];
    s->rA = v[VR_RIPA]; s->nA = v[VR_RIPA_N]; s->phA = v[VR_RIPA_PH];
    s->rB = v[VR_RIPB]; s->nB = v[VR_RIPB_N]; s->phB = v[VR_RIPB_PH];
    s->qa = 2.0 * M_PI / v[VR_ENC_COUNTS];
    s->qx = v[VR_SCALE_RES] * 1e-6;
    s->x0 = v[VR_X_START] * 1e-3;
    s->r1 = v[VR_ORB_R1]; s->r2 = v[VR_ORB_R2]; s->ph2 = v[VR_ORB_PH2];
    s->lc_noise = v[VR_LC_NOISE];
    cut_setup(&s->st, v);
    s->H_last = -1.0;                   /* re-derive the sub-step too (tau_cur may have changed) */
    d->dirty = 0;
}

int fg_model_check(FgInst *c, const char *fn) {
    const double *v = fg_data(c)->v;
    if (v[VR_T_STAT] < v[VR_T_COUL]) {
        fg_log_error(c, "%s: T_stat = %g N.m is invalid: expected >= T_coul = %g N.m (breakaway "
                     "above sliding friction)", fn, v[VR_T_STAT], v[VR_T_COUL]);
        return 0;
    }
    return cut_check(c, v, fn);
}

/* friction torque and its slope (for the linearly implicit speed update) */
static double friction(const BS *s, double w, double *slope) {
    return stribeck_friction(w, s->Tc, s->dTs, s->ws_inv, s->sexp, s->wreg_inv, s->b, slope);
}

static void outputs(FgData *d) {
    BS *s = (BS *)d->model.bytes;
    double *v = d->v;
    double F = s->Fc + s->Fr;
    /* two Gaussians per communication point, always: same seed + steps -> same outputs */
    double n_i = fg_gauss(d), n_f = fg_gauss(d);
    v[VR_IQ_MEAS] = (s->i + s->inoise * n_i) * TO_MA;
    v[VR_SCALE_POS] = floor(s->x / s->qx) * s->qx * TO_MM;
    v[VR_MOTOR_ANGLE] = floor(s->th / s->qa) * s->qa * TO_DEG;
    v[VR_LOAD_CELL] = F + s->lc_noise * n_f;
    v[VR_THRUST] = F;
    v[VR_RIPPLE] = s->Fr;
    v[VR_TIP_POS] = s->x * TO_MM;
    v[VR_TABLE_VEL] = s->v * TO_MM;
    v[VR_MOTOR_VEL] = s->w * (60.0 / (2.0 * M_PI));
    v[VR_FRICTION] = s->tf;
    cut_layer_at(&s->st, s->x, &v[VR_LAYER], &v[VR_MATERIAL]);
}

void fg_model_init(FgData *d) {
    BS *s = (BS *)d->model.bytes;
    memset(s, 0, sizeof *s);
    derive(d);
    s->x = s->x0;          /* nut at the table: screw unloaded */
    s->front = s->x0;      /* a start inside the stack means pre-drilled to there */
    outputs(d);
}

void fg_model_step(FgData *d, double H) {
    BS *s = (BS *)d->model.bytes;
    if (d->dirty) derive(d);
    if (H != s->H_last) {
        s->nsub = (int)ceil(H / (d->v[VR_H_SUB] * 1e-6) - 1e-9);
        if (s->nsub < 1) s->nsub = 1;
        s->h = H / s->nsub;
        s->alpha = 1.0 - exp(-s->h / (d->v[VR_TAU_CUR] * 1e-3));
        s->H_last = H;
    }
    const double h = s->h;
    double i_cmd = d->v[VR_IQ_REF] / TO_MA;
    if (i_cmd > s->imax) i_cmd = s->imax;
    if (i_cmd < -s->imax) i_cmd = -s->imax;
    const double n = fabs(d->v[VR_SPINDLE_N]) / 60.0;
    const double dphi = 2.0 * M_PI * d->v[VR_ORBIT_F] * h;
    for (int k = 0; k < s->nsub; k++) {
        double Fs = s->k * (s->x0 + s->p * s->th - s->x) + s->d * (s->p * s->w - s->v);
        s->Fc = cut_step(&s->st, &s->front, s->x, s->v, n, h);
        s->Fr = s->Fc > 0.0 ? s->Fc * (s->r1 * sin(s->phi) + s->r2 * sin(2.0 * s->phi + s->ph2)) : 0.0;
        double tau_r = s->rA * sin(s->nA * s->th + s->phA) + s->rB * sin(s->nB * s->th + s->phB);
        double slope;
        s->tf = friction(s, s->w, &slope);
        if (slope < 0.0) slope = 0.0;
        /* motor: linearly implicit in the friction (stiff near w = 0), explicit in the rest */
        s->w += h * (s->Kt * s->i - tau_r - s->p * Fs - s->tf) / (s->J + h * slope);
        s->v += h * (Fs - s->Fc - s->Fr) / s->m;
        s->th += h * s->w;
        s->x += h * s->v;
        s->i += s->alpha * (i_cmd - s->i);
        s->phi += dphi;
        if (s->phi >= 2.0 * M_PI) s->phi -= 2.0 * M_PI;
        if (s->phi < 0.0) s->phi += 2.0 * M_PI;
    }
    outputs(d);
}
