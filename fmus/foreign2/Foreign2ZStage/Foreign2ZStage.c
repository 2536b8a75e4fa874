/* Foreign2ZStage: vertical linear-motor z stage with a spring gravity compensator, a spindle
 * on a compliant mount and a saturating iron-core motor; FMI 2.0 co-simulation over the
 * foreign2 glue (f2core.c, f2fmi2.c). Equations and true values: README.md beside this file.
 * Interface in inch, % of rated current, rpm; SI inside. */
#include <math.h>
#include <string.h>

#include "f2core.h"
#include "f2stack.h"
#include "Foreign2ZStage_vars.h"

const F2Var f2_vars[] = {F2_VAR_ROWS};
const int f2_nvars = sizeof f2_vars / sizeof f2_vars[0];
const char f2_token[] = F2_TOKEN;
const unsigned f2_seed_vr = V_seed;

#define INCH 0.0254

typedef struct {
    F2Stack st;
    double z1, v1, z2, v2, i, c;          /* slide, spindle [m, m/s], current [A], cut front [m] */
    double F_cut, F_f, F_comp;            /* last thrust, friction, compensator force [N] */
    /* derived from the parameters */
    double m1, m2, km, cm, Kf0, ir, sat, kr, kkf, kph, cog1, kcog, cog2, cph2;
    double W, Fc0, kc, imax, ibias, igain, inoise, Fc, dFs, vs, sexp, visc, vreg, q, lc;
    double H_last, h, alpha;
    int nsub;
} Stage;

typedef char stage_fits[sizeof(Stage) <= F2_MODEL_BYTES ? 1 : -1];

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
    m->imax = p[V_i_max];
    m->ibias = p[V_i_bias] * 1e-3;
    m->igain = 1.0 + p[V_i_gain] * 0.01;
    m->inoise = p[V_i_noise] * 1e-3;
    m->Fc = p[V_F_c];
    m->dFs = p[V_F_s] - p[V_F_c];
    m->vs = p[V_v_s] * 1e-3;
    m->sexp = p[V_s_exp];
    m->visc = p[V_visc];
    m->vreg = p[V_v_reg] * 1e-6;
    m->q = p[V_enc_res] * 1e-9;
    m->lc = p[V_dyn_noise];
    f2s_setup(&m->st, p);
    m->H_last = -1.0;
    s->stale = 0;
}

int f2_model_check(F2Inst *c, const char *fn) {
    const double *p = c->s.val;
    if (p[V_F_s] < p[V_F_c]) {
        f2_log(c, 1, "%s: F_s = %g N is refused: expected >= F_c = %g N (breakaway at or above sliding "
               "friction)", fn, p[V_F_s], p[V_F_c]);
        return 0;
    }
    int bad = f2s_bad_layer(p);
    if (bad) {
        f2_log(c, 1, "%s: t%d = %g mm is refused: expected > 0 for a layer in use (n_layers = %d)", fn, bad,
               p[F2S_T1 + bad - 1], (int)p[V_n_layers]);
        return 0;
    }
    return 1;
}

static void outputs(F2State *s) {
    Stage *m = (Stage *)s->m.raw;
    double *p = s->val;
    double ni = f2_normal(s), nf = f2_normal(s);   /* always two draws: runs repeat bit for bit */
    p[V_z_enc] = floor(m->z1 / m->q) * m->q / INCH;
    p[V_i_fbk] = (m->igain * m->i + m->ibias + m->inoise * ni) / m->ir * 100.0;
    p[V_dyno_fz] = m->F_cut + m->lc * nf;
    p[V_f_thrust] = m->F_cut;
    p[V_tip_z] = m->z2 / INCH;
    p[V_slide_v] = m->v1 / INCH;
    p[V_f_guide] = m->F_f;
    p[V_f_comp] = m->F_comp;
    f2s_where(&m->st, m->z2, &p[V_layer], &p[V_material]);
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
    double r = m->i / m->ir;
    return m->Kf0 * (1.0 - m->sat * r * r) * (1.0 + m->kr * sin(m->kkf * m->z1 + m->kph)) * m->i;
}

void f2_model_step(F2State *s, double H) {
    Stage *m = (Stage *)s->m.raw;
    if (s->stale) derive(s);
    if (H != m->H_last) {
        m->nsub = (int)ceil(H / (s->val[V_h_sub] * 1e-6) - 1e-9);
        if (m->nsub < 1) m->nsub = 1;
        m->h = H / m->nsub;
        m->alpha = 1.0 - exp(-m->h / (s->val[V_tau_i] * 1e-3));
        m->H_last = H;
    }
    const double h = m->h, n = fabs(s->val[V_spindle]) / 60.0;
    double i_cmd = s->val[V_i_set] * 0.01 * m->ir;
    i_cmd = i_cmd > m->imax ? m->imax : i_cmd < -m->imax ? -m->imax : i_cmd;
    for (int k = 0; k < m->nsub; k++) {
        m->F_cut = f2s_step(&m->st, &m->c, m->z2, m->v2, n, h);
        double Fm = m->km * (m->z2 - m->z1) + m->cm * (m->v2 - m->v1);
        double cog = m->cog1 * sin(m->kcog * m->z1) + m->cog2 * sin(2.0 * m->kcog * m->z1 + m->cph2);
        m->F_comp = m->Fc0 + m->kc * m->z1;
        double slope;
        m->F_f = f2_friction(m->v1, m->Fc, m->dFs, m->vs, m->sexp, m->vreg, m->visc, &slope);
        if (slope < 0.0) slope = 0.0;
        /* linearly implicit in the friction (stiff at creep speeds), explicit elsewhere */
        m->v1 += h * (motor_force(m) + m->W - m->F_comp - cog - m->F_f + Fm) / (m->m1 + h * slope);
        m->v2 += h * (-Fm - m->F_cut) / m->m2;
        m->z1 += h * m->v1;
        m->z2 += h * m->v2;
        m->i += m->alpha * (i_cmd - m->i);
    }
    outputs(s);
}
