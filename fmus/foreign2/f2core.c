/* Version-independent part of the foreign2 FMI glue: see f2core.h. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "f2core.h"

const F2Var *f2_find(unsigned vr) {
    for (int k = 0; k < f2_nvars; k++)
        if (f2_vars[k].vr == vr) return &f2_vars[k];
    return NULL;
}

void f2_log(F2Inst *c, int is_error, const char *fmt, ...) {
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (c->emit && (is_error || c->logging)) c->emit(c, is_error, msg);
}

void f2_reset(F2Inst *c) {
    memset(&c->s, 0, sizeof c->s);
    for (int k = 0; k < f2_nvars; k++) c->s.val[f2_vars[k].vr] = f2_vars[k].start;
    c->s.stale = 1;
    c->phase = F2_INSTANTIATED;
}

static int in_range(const F2Var *v, double x) {
    if (!isfinite(x)) return 0;
    if (v->type == F2_INT && x != floor(x)) return 0;
    return v->kind >= F2_IN || (x >= v->lo && x <= v->hi);
}

static const char *unit_of(const F2Var *v) { return v->unit[0] ? v->unit : "1"; }

int f2_set(F2Inst *c, const char *fn, unsigned vr, double x) {
    const F2Var *v = f2_find(vr);
    if (!v) {
        f2_log(c, 1, "%s: no variable has value reference %u", fn, vr);
        return 0;
    }
    if (v->kind == F2_OUT) {
        f2_log(c, 1, "%s: %s is an output and cannot be set", fn, v->name);
        return 0;
    }
    if (v->kind == F2_FIXED && c->phase >= F2_RUN) {
        f2_log(c, 1, "%s: %s is a fixed parameter: it can only be set before initialisation ends", fn, v->name);
        return 0;
    }
    if (!in_range(v, x)) {
        f2_log(c, 1, "%s: %s = %g [%s] is refused: expected a finite %s in %g .. %g", fn, v->name, x,
               unit_of(v), v->type == F2_INT ? "integer" : "value", v->lo, v->hi);
        return 0;
    }
    c->s.val[vr] = x;
    if (v->kind <= F2_TUNE) c->s.stale = 1;
    return 1;
}

int f2_get(F2Inst *c, const char *fn, unsigned vr, double *x) {
    if (!f2_find(vr)) {
        f2_log(c, 1, "%s: no variable has value reference %u", fn, vr);
        return 0;
    }
    *x = c->s.val[vr];
    return 1;
}

int f2_check_all(F2Inst *c, const char *fn) {
    for (int k = 0; k < f2_nvars; k++) {
        const F2Var *v = &f2_vars[k];
        if (v->kind <= F2_TUNE && !in_range(v, c->s.val[v->vr])) {
            f2_log(c, 1, "%s: %s = %g [%s] is out of range: expected %g .. %g", fn, v->name,
                   c->s.val[v->vr], unit_of(v), v->lo, v->hi);
            return 0;
        }
    }
    return f2_model_check(c, fn);
}

int f2_enter_run(F2Inst *c, const char *fn) {
    if (!f2_check_all(c, fn)) {
        c->phase = F2_FAILED;
        return 0;
    }
    /* splitmix the seed so that seeds 1, 2, 3 give unrelated sequences */
    uint64_t z = (uint64_t)c->s.val[f2_seed_vr] + 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    c->s.rng = (z ^ (z >> 31)) | 1ull;
    c->s.have_spare = 0;
    f2_model_init(&c->s);
    c->phase = F2_RUN;
    return 1;
}

int f2_do_step(F2Inst *c, const char *fn, double t, double H) {
    if (c->phase != F2_RUN) {
        f2_log(c, 1, "%s: called outside step mode", fn);
        return 0;
    }
    if (!(H > 0.0) || !isfinite(H)) {
        f2_log(c, 1, "%s: communication step %g s is refused: expected a finite step > 0", fn, H);
        return 0;
    }
    if (fabs(t - c->s.t) > 1e-9 * (1.0 + fabs(t))) {
        f2_log(c, 1, "%s: current time %.12g s does not match the FMU's time %.12g s", fn, t, c->s.t);
        return 0;
    }
    f2_model_step(&c->s, H);
    c->s.t = t + H;
    for (int k = 0; k < f2_nvars; k++) {
        if (f2_vars[k].kind == F2_OUT && !isfinite(c->s.val[f2_vars[k].vr])) {
            f2_log(c, 1, "%s: the model diverged at t = %g s (%s is not finite)", fn, c->s.t, f2_vars[k].name);
            c->phase = F2_FAILED;
            return 0;
        }
    }
    return 1;
}

static double uniform(F2State *s) {
    s->rng ^= s->rng >> 12;
    s->rng ^= s->rng << 25;
    s->rng ^= s->rng >> 27;
    return ((s->rng * 0x2545F4914F6CDD1Dull) >> 11) * (1.0 / 9007199254740992.0);
}

double f2_normal(F2State *s) {
    if (s->have_spare) {
        s->have_spare = 0;
        return s->spare;
    }
    /* Box-Muller: two normals from two uniforms, the second kept */
    double u1 = uniform(s), u2 = uniform(s);
    if (u1 < 1e-300) u1 = 1e-300;
    double r = sqrt(-2.0 * log(u1)), a = 2.0 * M_PI * u2;
    s->spare = r * sin(a);
    s->have_spare = 1;
    return r * cos(a);
}

F2Inst *f2_new(const char *name, void (*emit)(F2Inst *, int, const char *), const void *cb, void *env,
               int logging) {
    F2Inst *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    strncpy(c->name, name ? name : "foreign2", sizeof c->name - 1);
    c->cb = cb;
    c->env = env;
    c->emit = emit;
    c->logging = logging ? 1 : 0;
    f2_reset(c);
    return c;
}

static int copy_state(void **state, const void *from) {
    if (!*state) *state = malloc(sizeof(F2State));
    if (!*state) return 0;
    memcpy(*state, from, sizeof(F2State));
    return 1;
}

int f2_state_get(F2Inst *c, void **state) { return copy_state(state, &c->s); }

int f2_state_set(F2Inst *c, const void *state) {
    if (!state) return 0;
    memcpy(&c->s, state, sizeof(F2State));
    return 1;
}

void f2_state_free(void **state) {
    free(*state);
    *state = NULL;
}

int f2_state_pack(const void *state, void *bytes, size_t size) {
    if (size < sizeof(F2State)) return 0;
    memcpy(bytes, state, sizeof(F2State));
    return 1;
}

int f2_state_unpack(const void *bytes, void **state) { return copy_state(state, bytes); }
