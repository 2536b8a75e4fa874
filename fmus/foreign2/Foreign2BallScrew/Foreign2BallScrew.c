/* Foreign2BallScrew: ball-screw orbital-drilling feed drive on a compliant frame, with nut
 * backlash, a torque constant that drifts with the winding temperature and a biased current
 * sensor; FMI 3.0 co-simulation over the foreign2 glue (f2core.c, f2fmi3.c). Equations and
 * true values: README.md beside this file. Interface in A, um, rev, rpm; SI inside. */
#include <math.h>
#include <string.h>

#include "f2core.h"
#include "f2stack.h"
#include "Foreign2BallScrew_vars.h"

const F2Var f2_vars[] = {F2_VAR_ROWS};
const int f2_nvars = sizeof f2_vars / sizeof f2_vars[0];
const char f2_token[] = F2_TOKEN;
const unsigned f2_seed_vr = V_seed;

typedef struct {
    F2Stack st;
    double th, w, x, v, y, vy, i, T, c, phi;  /* motor [rad, rad/s], table on frame [m, m/s], frame
                                                 [m, m/s], current [A], winding [degC], front [m], orbit [rad] */
    double F_c, F_r, T_f, Kt;                 /* last contact force, ripple [N], friction [N m], Kt [N m/A] */
    /* derived from the parameters */
    double J, mt, p, ks, ds, hb, mf, kf, df, Kt20, tc, Tamb, RR, Rth_q, inv_tau_th;
    double imax, ibias, igain, inoise, Tc, dTs, ws, sexp, bv, wreg;
    double ra[3], rn[3], rph[3], o1, o2, o2ph, o3, o3ph, qa, qx, lc;
    double H_last, h, alpha;
    int nsub;
} Drive;

typedef char drive_fits[sizeof(Drive) <= F2_MODEL_BYTES ? 1 : -1];

static void derive(F2State *s) {
    Drive *m = (Drive *)s->m.raw;
    const double *p = s->val;
    m->J = p[V_J_m];
    m->mt = p[V_m_tab];
    m->p = p[V_lead] * 1e-3 / (2.0 * M_PI);
    m->ks = p[V_k_scr] * 1e6;
    m->ds = p[V_d_scr];
    m->hb = 0.5 * p[V_backlash] * 1e-6;
    m->mf = p[V_m_frm];
    m->kf = p[V_k_frm] * 1e6;
    m->df = p[V_d_frm];
    m->Kt20 = p[V_Kt20];
    m->tc = p[V_kt_tc] * 0.01;
    m->Tamb = p[V_T_amb];
    m->RR = p[V_R_w] * p[V_R_th];
    m->Rth_q = p[V_R_th] * p[V_q_spin] * 1e-3;   /* K per rpm of spindle speed */
    m->inv_tau_th = 1.0 / p[V_tau_th];
    m->imax = p[V_i_max];
    m->ibias = p[V_i_bias] * 1e-3;
    m->igain = 1.0 + p[V_i_gain] * 0.01;
    m->inoise = p[V_i_noise] * 1e-3;
    m->Tc = p[V_T_c];
    m->dTs = p[V_T_s] - p[V_T_c];
    m->ws = p[V_w_s];
    m->sexp = p[V_s_exp];
    m->bv = p[V_b_v];
    m->wreg = p[V_w_reg];
    for (int k = 0; k < 3; k++) {   /* rip1.., rip1_n.., rip1_ph.. are spaced by 3 value references */
        m->ra[k] = p[V_rip1 + 3 * k];
        m->rn[k] = p[V_rip1_n + 3 * k];
        m->rph[k] = p[V_rip1_ph + 3 * k];
    }
    m->o1 = p[V_orb1] * 0.01;
    m->o2 = p[V_orb2] * 0.01;
    m->o2ph = p[V_orb2_ph];
    m->o3 = p[V_orb3] * 0.01;
    m->o3ph = p[V_orb3_ph];
    m->qa = 2.0 * M_PI / p[V_enc_cpr];
    m->qx = p[V_scale_res] * 1e-6;
    m->lc = p[V_dyn_noise];
    f2s_setup(&m->st, p);
    m->H_last = -1.0;
    s->stale = 0;
}

int f2_model_check(F2Inst *c, const char *fn) {
    const double *p = c->s.val;
    if (p[V_T_s] < p[V_T_c]) {
        f2_log(c, 1, "%s: T_s = %g N.m is refused: expected >= T_c = %g N.m (breakaway at or above sliding "
               "friction)", fn, p[V_T_s], p[V_T_c]);
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
    Drive *m = (Drive *)s->m.raw;
    double *p = s->val;
    double ni = f2_normal(s), nf = f2_normal(s);   /* always two draws: runs repeat bit for bit */
    p[V_i_act] = m->igain * m->i + m->ibias + m->inoise * ni;
    p[V_lin_scale] = floor(m->x / m->qx) * m->qx * 1e6;
    p[V_rotor] = floor(m->th / m->qa) * m->qa / (2.0 * M_PI);
    p[V_dyno] = m->F_c + m->F_r + m->lc * nf;
    p[V_f_axial] = m->F_c + m->F_r;
    p[V_f_orb] = m->F_r;
    p[V_tool_x] = (m->x + m->y) * 1e6;
    p[V_table_v] = m->v * 1e6;
    p[V_rotor_v] = m->w * 60.0 / (2.0 * M_PI);
    p[V_t_fric] = m->T_f;
    p[V_winding_T] = m->T;
    p[V_kt_now] = m->Kt;
    p[V_frame_x] = m->y * 1e6;
    f2s_where(&m->st, m->x + m->y, &p[V_layer], &p[V_material]);
}

void f2_model_init(F2State *s) {
    Drive *m = (Drive *)s->m.raw;
    memset(m, 0, sizeof *m);
    derive(s);
    m->x = m->c = s->val[V_x_start] * 1e-6;
    m->th = m->x / m->p;                 /* nut centred in its backlash */
    m->T = s->val[V_T_start];
    m->Kt = m->Kt20 * (1.0 - m->tc * (m->T - 20.0));
    outputs(s);
}

/* axial force of the nut on the table: a spring with a dead band (backlash) that only pushes */
static double nut_force(const Drive *m) {
    double e = m->p * m->th - m->x, de = m->p * m->w - m->v;
    if (e > m->hb) {
        double F = m->ks * (e - m->hb) + m->ds * de;
        return F > 0.0 ? F : 0.0;
    }
    if (e < -m->hb) {
        double F = m->ks * (e + m->hb) + m->ds * de;
        return F < 0.0 ? F : 0.0;
    }
    return 0.0;
}

static void substep(Drive *m, double i_cmd, double n, double dphi, double h) {
    /* winding heat: copper losses and the spindle's heat (n in rev/s) */
    double T_ss = m->Tamb + m->RR * m->i * m->i + m->Rth_q * 60.0 * n;
    double X = m->x + m->y, V = m->v + m->vy;
    m->F_c = f2s_step(&m->st, &m->c, X, V, n, h);
    m->F_r = m->F_c > 0.0 ? m->F_c * (m->o1 * sin(m->phi) + m->o2 * sin(2.0 * m->phi + m->o2ph)
                                      + m->o3 * sin(3.0 * m->phi + m->o3ph)) : 0.0;
    double Fs = nut_force(m);
    double rip = 0.0;
    for (int k = 0; k < 3; k++) rip += m->ra[k] * sin(m->rn[k] * m->th + m->rph[k]);
    m->Kt = m->Kt20 * (1.0 - m->tc * (m->T - 20.0));
    double slope;
    m->T_f = f2_friction(m->w, m->Tc, m->dTs, m->ws, m->sexp, m->wreg, m->bv, &slope);
    if (slope < 0.0) slope = 0.0;
    m->w += h * (m->Kt * m->i - rip - m->T_f - m->p * Fs) / (m->J + h * slope);
    double a_frame = (-m->kf * m->y - m->df * m->vy - Fs) / m->mf;
    double a_table = (Fs - m->F_c - m->F_r) / m->mt;   /* absolute */
    m->vy += h * a_frame;
    m->v += h * (a_table - a_frame);
    m->th += h * m->w;
    m->x += h * m->v;
    m->y += h * m->vy;
    m->T += h * (T_ss - m->T) * m->inv_tau_th;
    m->i += m->alpha * (i_cmd - m->i);
    m->phi = fmod(m->phi + dphi, 2.0 * M_PI);
}

void f2_model_step(F2State *s, double H) {
    Drive *m = (Drive *)s->m.raw;
    if (s->stale) derive(s);
    if (H != m->H_last) {
        m->nsub = (int)ceil(H / (s->val[V_h_sub] * 1e-6) - 1e-9);
        if (m->nsub < 1) m->nsub = 1;
        m->h = H / m->nsub;
        m->alpha = 1.0 - exp(-m->h / (s->val[V_tau_i] * 1e-3));
        m->H_last = H;
    }
    double i_cmd = s->val[V_i_cmd];
    i_cmd = i_cmd > m->imax ? m->imax : i_cmd < -m->imax ? -m->imax : i_cmd;
    const double n = fabs(s->val[V_spindle]) / 60.0;
    const double dphi = 2.0 * M_PI * fabs(s->val[V_orbit]) / 60.0 * m->h;
    for (int k = 0; k < m->nsub; k++) substep(m, i_cmd, n, dphi, m->h);
    outputs(s);
}
