/* Foreign2BallScrew: ball-screw orbital-drilling feed drive on a compliant frame, with nut
 * backlash, a torque constant that drifts with the winding temperature and a biased current
 * sensor; FMI 3.0 co-simulation over the foreign2 glue (f2core.c, f2fmi3.c). Equations and
 * true values: README.md beside this file. Interface in A, um, rev, rpm; SI inside. */
#include <math.h>
#include <string.h>

#include "f2drive.h"
#include "Foreign2BallScrew_vars.h"

const F2Var f2_vars[] = {F2_VAR_ROWS};
const int f2_nvars = sizeof f2_vars / sizeof f2_vars[0];
const char f2_token[] = F2_TOKEN;
const unsigned f2_seed_vr = V_seed;

typedef struct {
    F2Drive d;                                /* amplifier, bearing friction, stack, sub-steps */
    double th, w, x, v, y, vy, T, c, phi;     /* motor [rad, rad/s], table on frame [m, m/s], frame
                                                 [m, m/s], winding [degC], front [m], orbit [rad] */
    double F_c, F_r, T_f, Kt;                 /* last contact force, ripple [N], friction [N m], Kt [N m/A] */
    /* derived from the parameters */
    double J, mt, p, ks, ds, hb, mf, kf, df, Kt20, tc, Tamb, RR, Rth_q, inv_tau_th;
    double ra[3], rn[3], rph[3], o1, o2, o2ph, o3, o3ph, qa, qx;
} Drive;

typedef char drive_fits[sizeof(Drive) <= F2_MODEL_BYTES ? 1 : -1];
_Static_assert(V_i_noise == V_tau_i + 4 && V_w_reg == V_T_c + 5, "parameter blocks of f2drive.h");

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
    f2d_derive(&m->d, p, V_tau_i, V_T_c, 1.0, 1.0);    /* w_s and w_reg in rad/s */
    s->stale = 0;
}

int f2_model_check(F2Inst *c, const char *fn) { return f2d_check(c, fn, V_T_c); }

static void outputs(F2State *s) {
    Drive *m = (Drive *)s->m.raw;
    double *p = s->val;
    double ni = f2_normal(s), nf = f2_normal(s);   /* always two draws: runs repeat bit for bit */
    p[V_i_act] = f2d_sensed(&m->d, ni);
    p[V_lin_scale] = floor(m->x / m->qx) * m->qx * 1e6;
    p[V_rotor] = floor(m->th / m->qa) * m->qa / (2.0 * M_PI);
    p[V_dyno] = m->F_c + m->F_r + m->d.lc * nf;
    p[V_f_axial] = m->F_c + m->F_r;
    p[V_f_orb] = m->F_r;
    p[V_tool_x] = (m->x + m->y) * 1e6;
    p[V_table_v] = m->v * 1e6;
    p[V_rotor_v] = m->w * 60.0 / (2.0 * M_PI);
    p[V_t_fric] = m->T_f;
    p[V_winding_T] = m->T;
    p[V_kt_now] = m->Kt;
    p[V_frame_x] = m->y * 1e6;
    f2s_where(&m->d.st, m->x + m->y, &p[V_layer], &p[V_material]);
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
    double T_ss = m->Tamb + m->RR * m->d.i * m->d.i + m->Rth_q * 60.0 * n;
    double X = m->x + m->y, V = m->v + m->vy;
    m->F_c = f2s_step(&m->d.st, &m->c, X, V, n, h);
    m->F_r = m->F_c > 0.0 ? m->F_c * (m->o1 * sin(m->phi) + m->o2 * sin(2.0 * m->phi + m->o2ph)
                                      + m->o3 * sin(3.0 * m->phi + m->o3ph)) : 0.0;
    double Fs = nut_force(m);
    double rip = 0.0;
    for (int k = 0; k < 3; k++) rip += m->ra[k] * sin(m->rn[k] * m->th + m->rph[k]);
    m->Kt = m->Kt20 * (1.0 - m->tc * (m->T - 20.0));
    double slope;
    m->T_f = f2d_friction(&m->d, m->w, &slope);
    m->w += h * (m->Kt * m->d.i - rip - m->T_f - m->p * Fs) / (m->J + h * slope);
    double a_frame = (-m->kf * m->y - m->df * m->vy - Fs) / m->mf;
    double a_table = (Fs - m->F_c - m->F_r) / m->mt;   /* absolute */
    m->vy += h * a_frame;
    m->v += h * (a_table - a_frame);
    m->th += h * m->w;
    m->x += h * m->v;
    m->y += h * m->vy;
    m->T += h * (T_ss - m->T) * m->inv_tau_th;
    f2d_current(&m->d, i_cmd);
    m->phi = fmod(m->phi + dphi, 2.0 * M_PI);
}

void f2_model_step(F2State *s, double H) {
    Drive *m = (Drive *)s->m.raw;
    if (s->stale) derive(s);
    f2d_substeps(&m->d, H, s->val[V_h_sub], s->val[V_tau_i]);
    const double i_cmd = f2d_limit(&m->d, s->val[V_i_cmd]);
    const double n = fabs(s->val[V_spindle]) / 60.0;
    const double dphi = 2.0 * M_PI * fabs(s->val[V_orbit]) / 60.0 * m->d.h;
    for (int k = 0; k < m->d.nsub; k++) substep(m, i_cmd, n, dphi, m->d.h);
    outputs(s);
}
