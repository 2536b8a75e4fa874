/* Several C-kernel blocks in one call (cosim/loop/kernel_group.py, issue #15).
 *
 * The master would pay one ctypes call (~0.5-1 us with the copies) per block and sample;
 * a group of blocks due at the same steps runs here in one. Member j reads its inputs as
 * s * buf[idx] + o (a connection's scale and offset) and writes its outputs into buf at
 * y_off. The outputs stay in buf between calls, so a member reading a later member's
 * output sees the previous sample's value -- as it would on the master's bus.
 * `buf` is the group's own [t, the group's inputs from the bus..., every member's outputs...]
 * (kernel_group_step), or the entire bus of a fused loop (fused_steps.c).
 */
#define GROUP_MAX_IN 32

typedef void (*kernel_step)(void *state, double t, const double *u, double *y);

typedef struct {
    kernel_step fn;
    void *state;
    long n_in, in_at, y_off;      /* inputs: rows in_at .. in_at + n_in of `wiring` */
} Member;

typedef struct {
    long n;                       /* members */
    Member *members;
    const double *wiring;         /* rows [idx, scale, offset] */
} Group;

void kernel_group_run(const Group *g, double t, double *buf)
{
    double u[GROUP_MAX_IN];
    for (long j = 0; j < g->n; j++) {
        const Member *m = g->members + j;
        const double *w = g->wiring + 3 * m->in_at;
        for (long k = 0; k < m->n_in; k++, w += 3)
            u[k] = w[1] == 1.0 && w[2] == 0.0 ? buf[(long)w[0]] : w[1] * buf[(long)w[0]] + w[2];
        m->fn(m->state, t, u, buf + m->y_off);
    }
}

void kernel_group_step(const Group *g, double *buf)
{
    kernel_group_run(g, buf[0], buf);
}
