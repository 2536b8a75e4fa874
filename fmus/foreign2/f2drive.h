/* Feed-drive parts that both foreign2 plants share (issue 20), written apart from fmus/common
 * and fmus/foreign: the current amplifier (limit, first-order current loop, biased and noisy
 * sensor), the guide / bearing friction, the drill and stack with its dynamometer noise, the
 * internal sub-steps of a communication step and the cross-parameter checks.
 *
 * A plant embeds F2Drive in its model struct and keeps two parameter blocks in this order of
 * value references (fmus/foreign2/variables.py writes them so):
 *   amplifier  a .. a+4: tau_i [ms], i_max [A], i_bias [mA], i_gain [%], i_noise [mA]
 *   friction   f .. f+5: Coulomb, breakaway (>= Coulomb), Stribeck speed, Stribeck exponent,
 *                        viscous, regularisation speed (force or torque in the plant's units) */
#ifndef F2DRIVE_H
#define F2DRIVE_H

#include "f2core.h"
#include "f2stack.h"

typedef struct {
    F2Stack st;                             /* drill and stack */
    double i;                               /* actual current [A] */
    double imax, ibias, igain, inoise;      /* limit, sensor offset [A], gain [1], noise [A] */
    double Fc, dFs, vs, sexp, visc, vreg;   /* friction: Coulomb, breakaway - Coulomb, speeds in SI */
    double lc;                              /* dynamometer noise [N] */
    double H_last, h, alpha;                /* for the last communication step H: sub-step [s] and
                                               current-loop factor */
    int nsub;
} F2Drive;

/* parameters of the two blocks at value references a (amplifier) and f (friction); vs_si and
 * vreg_si convert the Stribeck and regularisation speeds to SI; invalidates the sub-steps */
void f2d_derive(F2Drive *d, const double *val, unsigned a, unsigned f, double vs_si, double vreg_si);
/* breakaway >= Coulomb friction (block at f) and a thickness > 0 for every layer in use;
 * 0 + log on failure */
int f2d_check(F2Inst *c, const char *fn, unsigned f);
/* sub-steps of H [s] no longer than h_sub [us], with the current loop's tau_i [ms] */
void f2d_substeps(F2Drive *d, double H, double h_sub, double tau_i);
double f2d_limit(const F2Drive *d, double i_cmd);           /* the command within +-i_max */
void f2d_current(F2Drive *d, double i_cmd);                 /* one sub-step of the current loop */
double f2d_sensed(const F2Drive *d, double noise);          /* current sensor [A], noise ~ N(0,1) */
/* Coulomb + Stribeck + viscous friction at speed v, regularised by v/sqrt(v^2 + vreg^2);
 * *slope is dF/dv >= 0 (for the linearly implicit velocity update) */
double f2d_friction(const F2Drive *d, double v, double *slope);

#endif
