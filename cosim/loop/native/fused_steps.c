/* Entire co-simulation steps in C (cosim/loop/fused.py): the steps in which only C blocks run.
 *
 * The Python loop (cosim/loop/algorithm.py) pays a ctypes call and a copy for every FMU read,
 * write and doStep and for every block group: ~7 us per step of Keio Fig. 4's two plants
 * on top of what the FMUs and the kernels compute. When nothing in a step needs Python
 * (no Python block due, no time event, not a recorded step), the same step runs here:
 * FMI 2.0 getReal -> the due kernel groups -> setReal -> doStep, on a C copy of the
 * master's bus with the master's slots, wiring and order. The Python loop keeps every
 * step that needs it and syncs the bus around them. The rows of the C steps go into
 * rec_buf, as the recorder's reader would compute them; the caller collects them.
 *
 * A status other than OK or Warning ends the call; the caller learns where (at_n, at_pos)
 * and handles it as the Python loop would (Discard from doStep may be a terminate request).
 */
#include <stdbool.h>
#include <stddef.h>
#include "kernel_group.c"

typedef int (*fmi2_get_real)(void *, const unsigned *, size_t, double *);
typedef int (*fmi2_set_real)(void *, const unsigned *, size_t, const double *);
typedef int (*fmi2_do_step)(void *, double, double, int);
typedef int (*fmi3_get_float64)(void *, const unsigned *, size_t, double *, size_t);
typedef int (*fmi3_set_float64)(void *, const unsigned *, size_t, const double *, size_t);
typedef int (*fmi3_do_step)(void *, double, double, bool, bool *, bool *, bool *, double *);

#define TERMINATES 100            /* cosim/fmi/slave.py TERMINATE_REQUESTED: the FMU asks to end the run */

typedef struct {
    void *comp;
    void *get, *set, *do_step;    /* FMI 2.0 or 3.0 functions (fmi3) */
    const unsigned *out_vr;
    long n_out, out_at;           /* outputs -> bus[out_at .. out_at + n_out) */
    const unsigned *in_vr;
    long n_in, in_at;             /* inputs: wiring rows in_at .. in_at + n_in */
    double *in_buf;
    long fmi3, n_out_vr, n_in_vr; /* FMI 3.0: value references may be fewer than values (arrays) */
} Slave;

typedef struct {
    const Group *group;
    long every;                   /* due at step n when n % every == 0 */
} Due;

typedef struct {
    long n_slaves;
    Slave *slaves;
    long n_groups;
    const Due *groups;
    const double *in_wiring;      /* rows [bus slot, scale, offset] of every FMU input */
    long n_conds;
    double *conds;                /* condition events: rows [slot, scale, offset, op, number, active] */
    long rec_every, rec_cols;     /* a row every rec_every steps (0: none) of rec_cols values */
    const double *rec_wiring;     /* rows [bus slot, scale, offset] of the recorded columns */
    double *rec_buf;              /* rows [t, values...] recorded by C steps ... */
    long rec_n;                   /* ... this many (the caller takes them and sets 0) */
    double *bus;
    double *beat;                 /* heartbeat: [0] step n, [1] FMU in doStep (-1: none) */
    double t0, h, stop_time, h_last;
    long n_last, n_short;
    long at_n, at_pos;            /* where a call stopped: step, position (see below) */
    double term_last;             /* FMI 3.0 terminate request: lastSuccessfulTime, if early */
    long term_early;
} Fused;

/* a step whose condition event holds is left to Python after its blocks: at_pos = FIRES */
#define FIRES (-1)

/* positions within a step: 0 .. S-1 read FMU k, S .. 2S-1 write FMU k - S, 2S .. 3S-1 step FMU k - 2S */

static double time_of(const Fused *f, long n)
{
    return n < f->n_last ? f->t0 + n * f->h : f->stop_time;
}

int fused_read(Fused *f, long n)
{
    f->beat[0] = (double)n;
    for (long k = 0; k < f->n_slaves; k++) {
        const Slave *s = f->slaves + k;
        if (s->n_out) {
            int st = s->fmi3 ? ((fmi3_get_float64)s->get)(s->comp, s->out_vr, (size_t)s->n_out_vr,
                                                           f->bus + s->out_at, (size_t)s->n_out)
                             : ((fmi2_get_real)s->get)(s->comp, s->out_vr, (size_t)s->n_out, f->bus + s->out_at);
            if (st > 1) { f->at_n = n; f->at_pos = k; return st; }
        }
    }
    return 0;
}

static void fused_blocks(Fused *f, long n)
{
    double t = time_of(f, n);
    for (long j = 0; j < f->n_groups; j++)
        if (n % f->groups[j].every == 0)
            kernel_group_run(f->groups[j].group, t, f->bus);
}

/* one group at step n (a step that also runs Python blocks: the loop keeps their order) */
void fused_group(Fused *f, long j, long n)
{
    kernel_group_run(f->groups[j].group, time_of(f, n), f->bus);
}

/* write every FMU's inputs, then step every FMU from t_n by h (the last step: h_last) */
int fused_advance(Fused *f, long n)
{
    double t = time_of(f, n), hn = n != f->n_short ? f->h : f->h_last;
    long S = f->n_slaves;
    for (long k = 0; k < S; k++) {
        Slave *s = f->slaves + k;
        if (!s->n_in)
            continue;
        const double *w = f->in_wiring + 3 * s->in_at;
        for (long i = 0; i < s->n_in; i++, w += 3)
            s->in_buf[i] = w[1] == 1.0 && w[2] == 0.0 ? f->bus[(long)w[0]] : w[1] * f->bus[(long)w[0]] + w[2];
        int st = s->fmi3 ? ((fmi3_set_float64)s->set)(s->comp, s->in_vr, (size_t)s->n_in_vr, s->in_buf,
                                                       (size_t)s->n_in)
                         : ((fmi2_set_real)s->set)(s->comp, s->in_vr, (size_t)s->n_in, s->in_buf);
        if (st > 1) { f->at_n = n; f->at_pos = S + k; return st; }
    }
    for (long k = 0; k < S; k++) {
        const Slave *s = f->slaves + k;
        f->beat[1] = (double)k;
        int st;
        if (s->fmi3) {
            bool event = false, terminate = false, early = false;
            double last = t;
            st = ((fmi3_do_step)s->do_step)(s->comp, t, hn, true, &event, &terminate, &early, &last);
            if (terminate && st < 2) {
                f->term_early = early;
                f->term_last = last;
                st = TERMINATES;
            }
        } else {
            st = ((fmi2_do_step)s->do_step)(s->comp, t, hn, 1);
        }
        if (st > 1) { f->at_n = n; f->at_pos = 2 * S + k; return st; }
    }
    f->beat[1] = -1.0;
    return 0;
}

/* does an active condition hold? (op: 0 >, 1 >=, 2 <, 3 <=, 4 ==, 5 !=; as the Python
 * loop computes it: scale * value + offset, then the comparison) */
static int fires(const Fused *f)
{
    for (long k = 0; k < f->n_conds; k++) {
        const double *c = f->conds + 6 * k;
        if (c[5] == 0.0)
            continue;
        double x = c[1] * f->bus[(long)c[0]] + c[2];
        int op = (int)c[3], hit = op == 0 ? x > c[4] : op == 1 ? x >= c[4] : op == 2 ? x < c[4]
                                : op == 3 ? x <= c[4] : op == 4 ? x == c[4] : x != c[4];
        if (hit)
            return 1;
    }
    return 0;
}

/* steps n0 .. n1 - 1, each complete (its row into rec_buf: room for them is the caller's);
 * 0, or the status that stopped it (at_n, at_pos): an FMI status, or FIRES after the
 * blocks of a step in which a condition event holds (its row not recorded) */
int fused_run(Fused *f, long n0, long n1)
{
    for (long n = n0; n < n1; n++) {
        int st = fused_read(f, n);
        if (st)
            return st;
        fused_blocks(f, n);
        if (f->n_conds && fires(f)) {
            f->at_n = n;
            f->at_pos = FIRES;
            return FIRES;
        }
        if (f->rec_every && n % f->rec_every == 0) {
            double *row = f->rec_buf + f->rec_n++ * (1 + f->rec_cols);
            const double *w = f->rec_wiring;
            row[0] = time_of(f, n);
            for (long k = 1; k <= f->rec_cols; k++, w += 3)
                row[k] = w[1] == 1.0 && w[2] == 0.0 ? f->bus[(long)w[0]] : w[1] * f->bus[(long)w[0]] + w[2];
        }
        st = fused_advance(f, n);
        if (st)
            return st;
    }
    return 0;
}
