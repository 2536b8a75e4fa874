/* Foreign2ZStage: vertical linear-motor z stage with a spring gravity compensator, a spindle
 * on a compliant mount and a saturating iron-core motor; FMI 2.0 co-simulation over the
 * foreign2 glue (f2core.c, f2fmi2.c). Equations and true values: README.md beside this file.
 * Interface in inch, % of rated current, rpm; SI inside. */
#include <math.h>
#include <string.h>

#include "f2drive.h"
#include "Foreign2ZStage_vars.h"

const F2Var f2_vars[] = {F2_VAR_ROWS};
const int f2_nvars = sizeof f2_vars / sizeof f2_vars[0];
const char f2_token[] = F2_TOKEN;
const unsigned f2_seed_vr = V_seed;

#define INCH 0.0254

typedef struct {
    F2Drive d;                            /* amplifier, guide friction, stack, sub-steps */
    double z1, v1, z2, v2, c;             /* slide, spindle [m, m/s], cut front [m] */
    double F_cut, F_f, F_comp;            /* last thrust, friction, compensator force [N] */
    /* derived from the parameters */
    double m1, m2, km, cm, Kf0, ir, sat, kr, kkf, kph, cog1, kcog, cog2, cph2;
    double W, Fc0, kc, q;
} Stage;

typedef char stage_fits[sizeof(Stage) <= F2_MODEL_BYTES ? 1 : -1];
_Static_assert(V_i_noise == V_tau_i + 4 && V_v_reg == V_F_c + 5, "parameter blocks of f2drive.h");

static void derive(F2State *s) {
    Stage *m = (Stage *)s->m.raw;
    const double *p = s->val;
    m->m1 = p[V_m_slide];
    m->m2 = p[V_m_spindle];
    m->km = p[V_k_mount] * 1e6;
    m->cm = p[V_c_mount];
    m->Kf0 = p[V_Kf0];
    m->ir = p[V_i_rated];
    m->sat = p[V_kf_sat];
    m->kr = p[V_kf_rip] * 0.01;
    m->kkf = 2.0 * M_PI / (p[V_kf_pitch] * 1e-3);
    m->kph = p[V_kf_ph];
    m->cog1 = p[V_cog1];
    m->kcog = 2.0 * M_PI / (p[V_cog_pitch] * 1e-3);
    m->cog2 = p[V_cog2];
    m->cph2 = p[V_cog2_ph];
    /* the mount is preloaded by the spindle's weight (tip = encoder at rest), so the whole
       weight acts on the slide */
    m->W = (p[V_m_slide] + p[V_m_spindle]) * p[V_g];
    m->Fc0 = p[V_comp_f0];
    m->kc = p[V_comp_k] * 1e3;
    m->q = p[V_enc_res] * 1e-9;
    f2d_derive(&m->d, p, V_tau_i, V_F_c, 1e-3, 1e-6);   /* v_s in mm/s, v_reg in um/s */
    s->stale = 0;
}

int f2_model_check(F2Inst *c, const char *fn) { return f2d_check(c, fn, V_F_c); }

static void outputs(F2State *s) {
    Stage *m = (Stage *)s->m.raw;
    double *p = s->val;
    double ni = f2_normal(s), nf = f2_normal(s);   /* always two draws: runs repeat bit for bit */
    p[V_z_enc] = floor(m->z1 / m->q) * m->q / INCH;
    p[V_i_fbk] = f2d_sensed(&m->d, ni) / m->ir * 100.0;
    p[V_dyno_fz] = m->F_cut + m->d.lc * nf;
    p[V_f_thrust] = m->F_cut;
    p[V_tip_z] = m->z2 / INCH;
    p[V_slide_v] = m->v1 / INCH;
    p[V_f_guide] = m->F_f;
    p[V_f_comp] = m->F_comp;
    f2s_where(&m->d.st, m->z2, &p[V_layer], &p[V_material]);
}

void f2_model_init(F2State *s) {
    Stage *m = (Stage *)s->m.raw;
    memset(m, 0, sizeof *m);
    derive(s);
    m->z1 = m->z2 = m->c = s->val[V_z_start] * INCH;
    m->F_comp = m->Fc0 + m->kc * m->z1;
    outputs(s);
}

static double motor_force(const Stage *m) {
    double r = m->d.i / m->ir;
    return m->Kf0 * (1.0 - m->sat * r * r) * (1.0 + m->kr * sin(m->kkf * m->z1 + m->kph)) * m->d.i;
}

void f2_model_step(F2State *s, double H) {
    Stage *m = (Stage *)s->m.raw;
    if (s->stale) derive(s);
    f2d_substeps(&m->d, H, s->val[V_h_sub], s->val[V_tau_i]);
    const double h = m->d.h, n = fabs(s->val[V_spindle]) / 60.0;
    const double i_cmd = f2d_limit(&m->d, s->val[V_i_set] * 0.01 * m->ir);
    for (int k = 0; k < m->d.nsub; k++) {
        m->F_cut = f2s_step(&m->d.st, &m->c, m->z2, m->v2, n, h);
        double Fm = m->km * (m->z2 - m->z1) + m->cm * (m->v2 - m->v1);
        double cog = m->cog1 * sin(m->kcog * m->z1) + m->cog2 * sin(2.0 * m->kcog * m->z1 + m->cph2);
        m->F_comp = m->Fc0 + m->kc * m->z1;
        double slope;
        m->F_f = f2d_friction(&m->d, m->v1, &slope);
        /* linearly implicit in the friction (stiff at creep speeds), explicit elsewhere */
        m->v1 += h * (motor_force(m) + m->W - m->F_comp - cog - m->F_f + Fm) / (m->m1 + h * slope);
        m->v2 += h * (-Fm - m->F_cut) / m->m2;
        m->z1 += h * m->v1;
        m->z2 += h * m->v2;
        f2d_current(&m->d, i_cmd);
    }
    outputs(s);
}
