/* Continuous Stribeck friction shared by the foreign plants (drive-side coordinate:
   motor speed [rad/s] and torque, or stage velocity [m/s] and force):

     f(w) = (c + ds exp(-(|w|/ws)^e)) tanh(w/wreg) + b w

   and its slope df/dw, which the linearly implicit speed update needs. */
#ifndef FOREIGN_STRIBECK_H
#define FOREIGN_STRIBECK_H

#include <math.h>

static inline double stribeck_friction(double w, double c, double ds, double ws_inv, double e,
                                       double wreg_inv, double b, double *slope) {
    double u = fabs(w) * ws_inv;
    double x = u > 0.0 ? exp(-pow(u, e)) : 1.0;
    double g = c + ds * x;
    double th = tanh(w * wreg_inv);
    double dg = u > 0.0 ? -ds * x * e * pow(u, e - 1.0) * ws_inv : 0.0;
    *slope = dg * (w >= 0.0 ? 1.0 : -1.0) * th + g * (1.0 - th * th) * wreg_inv + b;
    return g * th + b * w;
}

#endif
