/* One sample of drillcosim.controllers.adaptation.CuttingParameterAdaptation and OneStepDelay, in C
 * (issue #21).
 *
 * The same arithmetic as the Python steps, operation for operation (compiled with
 * -ffp-contract=off), so both give the same doubles; the Python stays the readable
 * reference and documents the choices (tests/test_adaptation_kernel.py compares them).
 * Every struct holds doubles only (indices and flags as 0.0 / 1.0 ...), mirrored field for
 * field by the ctypes structs in controllers/adaptation.py. Signature: (state, t, u, y).
 */
#include <math.h>

#define MAX(a, b) ((b) > (a) ? (b) : (a))   /* Python's max(a, b): a unless b > a */
#define ADAPT_MAX_STAGES 16                 /* stages incl. the fail-safe set */
#define ADAPT_MAX_LOG 64                    /* switches kept for the Python API's log */
#define ADAPT_N_OUT 9

typedef struct {
    /* settings */
    double n_stages, ramp_time, sample_period, fail_index;   /* fail_index < 0: none */
    double latch;                                            /* 0 none, 1 hold, 2 retract */
    double flag[ADAPT_MAX_STAGES];
    double param[3 * ADAPT_MAX_STAGES];                      /* rows feed, spindle, orbital */
    /* state */
    double index, value[3], start[3], t_switch, has_t_prev, t_prev;
    double failsafe, t_failsafe, settled, out[ADAPT_N_OUT];
    double n_log, log_t[ADAPT_MAX_LOG], log_index[ADAPT_MAX_LOG];
} Adaptation;

static int target_index(const Adaptation *s, double flag, double fail)
{
    if (s->failsafe != 0.0 || (fail >= 0.5 && s->fail_index >= 0.0))
        return (int)s->fail_index;
    int idx = 0;
    for (int i = 0; i < (int)s->n_stages; i++)
        if (flag >= s->flag[i] - 1e-9)
            idx = i;
    return idx;
}

static void switch_to(Adaptation *s, int idx, double t)
{
    for (int j = 0; j < 3; j++)
        s->start[j] = s->value[j];      /* blend from what is in force (also mid-ramp) */
    s->index = idx;
    s->t_switch = t;
    int n = (int)s->n_log;
    if (n < ADAPT_MAX_LOG) {
        s->log_t[n] = t;
        s->log_index[n] = idx;
    }
    s->n_log = n + 1;
}

/* u: flag, fail; y: feed_rate_cmd, spindle_speed, orbital_speed, stage, t_switch, ramp,
 * retract, failsafe, t_failsafe */
void adaptation_step(Adaptation *s, double t, const double *u, double *y)
{
    if (s->failsafe == 0.0 && u[1] >= 0.5 && s->latch != 0.0) {
        s->failsafe = s->latch;         /* latched: the flag is no longer trusted */
        s->t_failsafe = t;
        s->settled = 0.0;
    }
    int idx = target_index(s, u[0], u[1]);
    if (idx == (int)s->index && s->settled != 0.0) {
        s->has_t_prev = 1.0;
        s->t_prev = t;
        for (int j = 0; j < ADAPT_N_OUT; j++)
            y[j] = s->out[j];
        return;
    }
    if (idx != (int)s->index)
        switch_to(s, idx, t);
    const double *target = s->param + 3 * (int)s->index;
    double h = s->sample_period > 0.0 ? s->sample_period
             : (s->has_t_prev == 0.0 ? 0.0 : MAX(t - s->t_prev, 0.0));
    s->has_t_prev = 1.0;
    s->t_prev = t;
    double r;
    if (isnan(s->t_switch) || s->ramp_time <= 0.0) {
        r = 1.0;
    } else {
        double x = (t - s->t_switch + h) / s->ramp_time;
        r = x >= 1.0 ? 1.0 : 0.5 * (1.0 - cos(3.141592653589793 * MAX(x, 0.0)));
    }
    for (int j = 0; j < 3; j++)
        s->value[j] = s->start[j] + (target[j] - s->start[j]) * r;
    double *o = s->out;
    o[0] = s->value[0];
    o[1] = s->value[1];
    o[2] = s->value[2];
    o[3] = s->index;
    o[4] = s->t_switch;
    o[5] = r;
    o[6] = s->failsafe == 2.0 ? 1.0 : 0.0;
    o[7] = s->failsafe;
    o[8] = s->t_failsafe;
    s->settled = r == 1.0 ? 1.0 : 0.0;
    for (int j = 0; j < ADAPT_N_OUT; j++)
        y[j] = o[j];
}

typedef struct {
    double held;
} OneStepDelay;

/* y(t_k) = u(t_{k-1}) */
void one_step_delay_step(OneStepDelay *s, double t, const double *u, double *y)
{
    (void)t;
    y[0] = s->held;
    s->held = u[0];
}
