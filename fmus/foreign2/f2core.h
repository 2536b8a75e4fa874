/* Core of the foreign2 plants' FMI glue: one instance's values, range checks, noise and
 * logging, independent of the FMI version. f2fmi2.c (FMI 2.0 CS) and f2fmi3.c (FMI 3.0 CS)
 * are thin API layers over it; a plant model supplies its variable table (generated into
 * <Name>_vars.h by fmus/foreign2/build.py from the same rows as its modelDescription.xml) and
 * three hooks. Written for drillcosim issue 20 apart from fmus/common and fmus/foreign.
 *
 * All values live in F2State.val[vr] as doubles (Int32 parameters too), so saving an FMU
 * state is a copy of F2State. */
#ifndef F2CORE_H
#define F2CORE_H

#include <stddef.h>
#include <stdint.h>

#define F2_NVAL 160                 /* value references 0 .. F2_NVAL-1 */
#define F2_MODEL_BYTES 2048         /* the model's own plain-data states */

enum { F2_REAL = 0, F2_INT = 1 };
/* causality/variability class: fixed parameter, tunable parameter, input, output */
enum { F2_FIXED = 0, F2_TUNE = 1, F2_IN = 2, F2_OUT = 3 };

typedef struct {
    const char *name;
    unsigned vr;
    int type;                       /* F2_REAL / F2_INT */
    int kind;                       /* F2_FIXED .. F2_OUT */
    double start, lo, hi;           /* range checked for parameters */
    const char *unit;               /* for messages */
} F2Var;

typedef struct {
    double val[F2_NVAL];
    union { double align; unsigned char raw[F2_MODEL_BYTES]; } m;
    uint64_t rng;                   /* xorshift64* state */
    int have_spare;
    double spare;
    double t;                       /* communication time [s] */
    int stale;                      /* a parameter changed since the model last derived */
} F2State;

typedef enum { F2_INSTANTIATED, F2_INIT, F2_RUN, F2_DONE, F2_FAILED } F2Phase;

typedef struct F2Inst {
    F2State s;
    F2Phase phase;
    char name[128];
    void (*emit)(struct F2Inst *, int is_error, const char *msg);   /* set by the API layer */
    void *env;                      /* the API layer's callbacks and environment */
    const void *cb;
    int logging;
} F2Inst;

/* ---- supplied by the plant model ---- */
extern const F2Var f2_vars[];
extern const int f2_nvars;
extern const char f2_token[];       /* GUID / instantiation token */
extern const unsigned f2_seed_vr;   /* Int32 seed parameter */
int f2_model_check(F2Inst *c, const char *fn);    /* cross-parameter checks; 0 + log on failure */
void f2_model_init(F2State *s);                    /* states from parameters, then outputs */
void f2_model_step(F2State *s, double H);          /* advance by H [s], then outputs */

/* ---- supplied by f2core.c ---- */
void f2_reset(F2Inst *c);                          /* start values, fresh noise */
const F2Var *f2_find(unsigned vr);
/* set one value through the API; checks kind, phase and range; 0 + log on refusal */
int f2_set(F2Inst *c, const char *fn, unsigned vr, double x);
int f2_get(F2Inst *c, const char *fn, unsigned vr, double *x);
int f2_check_all(F2Inst *c, const char *fn);       /* ranges of every parameter + model check */
int f2_enter_run(F2Inst *c, const char *fn);       /* checks, seeds, model init */
int f2_do_step(F2Inst *c, const char *fn, double t, double H);
void f2_log(F2Inst *c, int is_error, const char *fmt, ...);
double f2_normal(F2State *s);                      /* N(0,1), reproducible from the seed */

/* ---- for the API layers (f2fmi2.c, f2fmi3.c) ---- */
/* a new instance with its start values (name NULL: "foreign2"); NULL if out of memory */
F2Inst *f2_new(const char *name, void (*emit)(F2Inst *, int, const char *), const void *cb, void *env,
               int logging);
/* FMU states are a copy of the plain-data F2State, allocated when *state is NULL; each returns 0
 * (and changes nothing) when out of memory, on a NULL state or a buffer shorter than F2State */
int f2_state_get(F2Inst *c, void **state);
int f2_state_set(F2Inst *c, const void *state);
void f2_state_free(void **state);
int f2_state_pack(const void *state, void *bytes, size_t size);
int f2_state_unpack(const void *bytes, void **state);     /* bytes: sizeof(F2State) of them */

#endif
