/* Drill and layered stack of the foreign plants (shared by ForeignBallScrew and
 * ForeignZStage; written independently of fmus/common/drill.c).
 *
 * Thrust law (steady cutting): F = K_mat (f_rev / 1 mm)^feed_exp, f_rev = feed per spindle
 * revolution, K_mat = thrust at 1 mm/rev (per-layer override kcK, else the material preset)
 * times (1 + wear_mat/100 * wear_holes). The tool tip meets the uncut material (the cut front
 * c) through a lightly damped contact spring (k_contact, d_contact); the front advances at
 * the feed per revolution the elastic force can cut: dc/dt = n (k_contact e / K_eff(c))^(1/x).
 * K_eff(c) blends the layers over the engagement length with a smoothstep (entry ramp and
 * layer changes) and falls quadratically with the remaining thickness r below exit_t in a
 * layer whose lower face is free (the last one, or one with a gap below): the push-out.
 * Equations and numbers: fmus/foreign/ForeignBallScrew/README.md. */
#ifndef FOREIGN_CUT_H
#define FOREIGN_CUT_H

#include "fglue.h"

/* value references of the drill/stack parameters (same in both plants) */
enum {
    VR_SURFACE = 60, VR_NLAYERS = 61, VR_MAT1 = 62, VR_T1 = 66, VR_GAP2 = 70, VR_KC1 = 73,
    VR_K_CFRP = 77, VR_K_TI = 78, VR_K_AL = 79, VR_FEED_EXP = 80, VR_ENGAGE = 81, VR_EXIT_T = 82,
    VR_K_CONTACT = 83, VR_D_CONTACT = 84, VR_WEAR_HOLES = 85, VR_WEAR_CFRP = 86,
    VR_WEAR_TI = 87, VR_WEAR_AL = 88, VR_LC_NOISE = 89, VR_SEED = 90
};

/* FgVar rows of the drill/stack parameters; the contact defaults differ per plant */
#define CUT_VARS(k_contact_default, d_contact_default)                                              \
    {"surface_pos", VR_SURFACE, FG_F64, FG_PARAM, 1.0, -1000, 1000, "mm"},                          \
    {"n_layers", VR_NLAYERS, FG_I32, FG_PARAM, 2, 1, 4, ""},                                        \
    {"mat1", VR_MAT1 + 0, FG_I32, FG_PARAM, 1, 1, 3, ""},                                           \
    {"mat2", VR_MAT1 + 1, FG_I32, FG_PARAM, 2, 1, 3, ""},                                           \
    {"mat3", VR_MAT1 + 2, FG_I32, FG_PARAM, 1, 1, 3, ""},                                           \
    {"mat4", VR_MAT1 + 3, FG_I32, FG_PARAM, 1, 1, 3, ""},                                           \
    {"t1", VR_T1 + 0, FG_F64, FG_PARAM, 5.0, 0, 100, "mm"},                                         \
    {"t2", VR_T1 + 1, FG_F64, FG_PARAM, 4.5, 0, 100, "mm"},                                         \
    {"t3", VR_T1 + 2, FG_F64, FG_PARAM, 0.0, 0, 100, "mm"},                                         \
    {"t4", VR_T1 + 3, FG_F64, FG_PARAM, 0.0, 0, 100, "mm"},                                         \
    {"gap2", VR_GAP2 + 0, FG_F64, FG_PARAM, 0.0, 0, 100, "mm"},                                     \
    {"gap3", VR_GAP2 + 1, FG_F64, FG_PARAM, 0.0, 0, 100, "mm"},                                     \
    {"gap4", VR_GAP2 + 2, FG_F64, FG_PARAM, 0.0, 0, 100, "mm"},                                     \
    {"kc1", VR_KC1 + 0, FG_F64, FG_TUNABLE, 0.0, 0, 1e6, "N"},                                      \
    {"kc2", VR_KC1 + 1, FG_F64, FG_TUNABLE, 0.0, 0, 1e6, "N"},                                      \
    {"kc3", VR_KC1 + 2, FG_F64, FG_TUNABLE, 0.0, 0, 1e6, "N"},                                      \
    {"kc4", VR_KC1 + 3, FG_F64, FG_TUNABLE, 0.0, 0, 1e6, "N"},                                      \
    {"K_cfrp", VR_K_CFRP, FG_F64, FG_TUNABLE, 6900.0, 1, 1e6, "N"},                                 \
    {"K_ti", VR_K_TI, FG_F64, FG_TUNABLE, 17300.0, 1, 1e6, "N"},                                    \
    {"K_al", VR_K_AL, FG_F64, FG_TUNABLE, 1150.0, 1, 1e6, "N"},                                     \
    {"feed_exp", VR_FEED_EXP, FG_F64, FG_TUNABLE, 0.8, 0.3, 1.0, ""},                               \
    {"engage", VR_ENGAGE, FG_F64, FG_TUNABLE, 0.15, 0.01, 5, "mm"},                                 \
    {"exit_t", VR_EXIT_T, FG_F64, FG_TUNABLE, 0.5, 0.01, 5, "mm"},                                  \
    {"k_contact", VR_K_CONTACT, FG_F64, FG_TUNABLE, k_contact_default, 0.1, 200, "N/um"},           \
    {"d_contact", VR_D_CONTACT, FG_F64, FG_TUNABLE, d_contact_default, 0, 1e5, "N.s/m"},            \
    {"wear_holes", VR_WEAR_HOLES, FG_F64, FG_TUNABLE, 0.0, 0, 1000, ""},                            \
    {"wear_cfrp", VR_WEAR_CFRP, FG_F64, FG_TUNABLE, 1.2, 0, 100, "%/hole"},                         \
    {"wear_ti", VR_WEAR_TI, FG_F64, FG_TUNABLE, 3.0, 0, 100, "%/hole"},                             \
    {"wear_al", VR_WEAR_AL, FG_F64, FG_TUNABLE, 0.4, 0, 100, "%/hole"},                             \
    {"lc_noise", VR_LC_NOISE, FG_F64, FG_TUNABLE, 0.8, 0, 100, "N"},                                \
    {"seed", VR_SEED, FG_I32, FG_PARAM, 1, 0, 2147483647.0, ""}

typedef struct {
    int n;
    double top[4], bot[4];     /* m, feed coordinate */
    int mat[4];
    int free_below[4];         /* lower face free (last layer or a gap below): push-out */
    double K[4];               /* N at 1 mm/rev, wear included */
    double K_floor;            /* N: below it the point cuts air (front follows the tip) */
    double inv_exp;            /* 1/feed_exp */
    double inv_L, inv_rex;     /* 1/m */
    double kw, dw;             /* N/m, N s/m */
} CutStack;

/* geometry (fixed) and coefficients (tunable) from the parameter values v[] */
void cut_setup(CutStack *st, const double *v);
/* used layers need a thickness > 0: logs and returns 0 otherwise */
int cut_check(FgInst *c, const double *v, const char *fn);
/* effective thrust coefficient [N at 1 mm/rev] at cut-front position c [m] */
double cut_keff(const CutStack *st, double c);
/* one sub-step h [s] of the contact and cut front *front [m] for tool tip x [m], tip velocity
 * v [m/s] and spindle speed n [rev/s]; returns the contact force on the tool [N, >= 0] */
double cut_step(const CutStack *st, double *front, double x, double v, double n, double h);
/* layer index (1..n, 0 = none) and material code (0 air) at tool tip x [m] */
void cut_layer_at(const CutStack *st, double x, double *layer, double *material);

#endif
