/* Drill and layered workpiece model, noise generator, guide friction and sub-stepping:
 * shared by both plant FMUs.
 * Equations: docs/plants.md. SI units; spindle/orbital speeds in rpm at the interface. */
#ifndef DRILLCOSIM_DRILL_H
#define DRILLCOSIM_DRILL_H

#include <stddef.h>
#include <stdint.h>

#define DRILL_MAX_LAYERS 4

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* ---------------------------------------------------------------- noise (xorshift64*) */
typedef struct {
    uint64_t s;
    int has_spare;
    double spare;
} Prng;

void prng_seed(Prng *r, int64_t seed);
double prng_uniform(Prng *r);   /* (0, 1) */
double prng_gauss(Prng *r);     /* N(0, 1), Box-Muller */

/* ---------------------------------------------------------------- machine */
/* Number of fixed internal sub-steps for a communication step H (snapped to whole
 * nanoseconds when within 1e-3 ns of them, drill.c), ceil(H/h_internal)
 * (at least 1); *hs = H / that number. */
int substeps(double H, double h_internal, double *hs);
/* Friction (force or torque, with the velocity v on the same side) of a guide or drive:
 * stuck (v == 0) it balances F_ext up to F_c + F_s (Karnopp); sliding it is
 * F_c + F_s exp(-(v/v_s)^2) against the motion plus the viscous b v. */
double stick_slip_friction(double F_ext, double v, double F_c, double F_s, double v_s, double b);

/* ---------------------------------------------------------------- drill / workpiece */
typedef struct {
    double surface;
    int n_layers;
    int material[DRILL_MAX_LAYERS];
    double thickness[DRILL_MAX_LAYERS];
    double gap[DRILL_MAX_LAYERS];
    double kc[DRILL_MAX_LAYERS];
    double kc_cfrp, kc_ti, kc_al, ti_descent;
    double ripple_ratio, ripple_phase;
    double k_contact, d_contact, engage_length, exit_thinning, gap_thinning;
    double wear_holes, wear_cfrp, wear_ti, wear_al;
    double F_dyn_noise, h_internal;
} DrillParams;

/* Fill a DrillParams from a generated ModelVars struct (same field names in both FMUs). */
#define DRILL_PARAMS_FROM_VARS(P, V) do {                                             \
    (P)->surface = (V)->surface; (P)->n_layers = (V)->n_layers;                       \
    (P)->material[0] = (V)->layer1_material; (P)->thickness[0] = (V)->layer1_thickness; \
    (P)->gap[0] = (V)->layer1_gap; (P)->kc[0] = (V)->layer1_kc;                       \
    (P)->material[1] = (V)->layer2_material; (P)->thickness[1] = (V)->layer2_thickness; \
    (P)->gap[1] = (V)->layer2_gap; (P)->kc[1] = (V)->layer2_kc;                       \
    (P)->material[2] = (V)->layer3_material; (P)->thickness[2] = (V)->layer3_thickness; \
    (P)->gap[2] = (V)->layer3_gap; (P)->kc[2] = (V)->layer3_kc;                       \
    (P)->material[3] = (V)->layer4_material; (P)->thickness[3] = (V)->layer4_thickness; \
    (P)->gap[3] = (V)->layer4_gap; (P)->kc[3] = (V)->layer4_kc;                       \
    (P)->kc_cfrp = (V)->kc_cfrp; (P)->kc_ti = (V)->kc_ti; (P)->kc_al = (V)->kc_al;    \
    (P)->ti_descent = (V)->ti_descent;                                                \
    (P)->ripple_ratio = (V)->ripple_ratio; (P)->ripple_phase = (V)->ripple_phase;     \
    (P)->k_contact = (V)->k_contact; (P)->d_contact = (V)->d_contact;                 \
    (P)->engage_length = (V)->engage_length; (P)->exit_thinning = (V)->exit_thinning; \
    (P)->gap_thinning = (V)->gap_thinning;                                            \
    (P)->wear_holes = (V)->wear_holes; (P)->wear_cfrp = (V)->wear_cfrp;               \
    (P)->wear_ti = (V)->wear_ti; (P)->wear_al = (V)->wear_al;                         \
    (P)->F_dyn_noise = (V)->F_dyn_noise; (P)->h_internal = (V)->h_internal;           \
} while (0)

/* Geometry and coefficients derived from DrillParams (rebuilt at every doStep). */
typedef struct {
    int n;
    double top[DRILL_MAX_LAYERS], bot[DRILL_MAX_LAYERS];
    double kc[DRILL_MAX_LAYERS];      /* incl. wear */
    double descent[DRILL_MAX_LAYERS]; /* 1/m, Ti only */
    double thin[DRILL_MAX_LAYERS];    /* thinning length of a free lower face (0 = supported) */
    int material[DRILL_MAX_LAYERS];
    double L;                         /* engagement length */
    double k, d;                      /* contact stiffness, damping */
    double ripple_ratio, ripple_phase;
} Stack;

/* Cutting state: c = cut front (feed coordinate of the uncut material under the tool
 * tip), phi = orbital angle [rad]. */
typedef struct {
    double c;
    double phi;
} CutState;

/* returns nonzero and a message naming the parameter when something is invalid */
int drill_validate(const DrillParams *p, char *msg, size_t n);
void drill_build(Stack *s, const DrillParams *p);
/* effective thrust coefficient at cut front c [N/(m/rev)] */
double drill_kc_eff(const Stack *s, double c);
/* DC thrust (contact force) for tool tip z, velocity v, spindle n_rps [rev/s] */
double drill_force_dc(const Stack *s, double kce, double c, double z, double v, double n_rps);
/* Thrust on the tool at tip z, velocity v: DC part (drill_force_dc) and orbital ripple
 * ripple_ratio F_dc sin(phi + ripple_phase) (Fang eq. 8); returns kc_eff at the cut front. */
double drill_thrust(const Stack *s, const CutState *cut, double z, double v, double n_rps,
                    double *F_dc, double *F_r);
/* advance the cut front over a sub-step in which the tool tip moved z0 -> z1 */
double drill_advance_front(const Stack *s, double kce, double c, double z0, double z1, double h,
                           double n_rps);
/* layer index (1..n, 0 = none) and material code at position z */
int drill_layer_at(const Stack *s, double z, int *material);

#endif
