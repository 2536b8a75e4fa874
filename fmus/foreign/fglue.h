/* Interface between the hand-written FMI 3.0 co-simulation glue (fglue.c) and one plant
 * model (ForeignBallScrew.c, ForeignZStage.c).
 *
 * Every variable's value lives in FgInst.v[vr] as a double, indexed by its value
 * reference (Int32 variables too: converted on get/set), so an FMU state is a memcpy of
 * FgInst.data. The model supplies the variable table (which must agree with its
 * hand-written modelDescription.xml: tests/test_foreign_plants.py checks the start values
 * through the FMI API) and four hooks. */
#ifndef FGLUE_H
#define FGLUE_H

#include <stdint.h>
#include <stddef.h>

#define FG_MAXVR 128        /* value references 0..127 (0 = time) */
#define FG_MODEL_BYTES 1024   /* room for the model's own plain-data state */

typedef enum { FG_F64, FG_I32 } FgType;
typedef enum { FG_PARAM, FG_TUNABLE, FG_INPUT, FG_OUTPUT } FgCaus;

typedef struct {
    const char *name;
    unsigned vr;
    FgType type;
    FgCaus caus;
    double start;
    double min, max;        /* checked for parameters and tunables (min > max: unchecked) */
    const char *unit;       /* for messages only */
} FgVar;

/* the plain-data part of an instance: copied whole for FMU states */
typedef struct {
    double v[FG_MAXVR];     /* variable values by value reference */
    union { double align; unsigned char bytes[FG_MODEL_BYTES]; } model;  /* the model's states and
                            derived constants (its own struct, plain data) */
    uint64_t rng_state, rng_inc;
    int have_spare;
    double spare;           /* second Gaussian of the polar method */
    double time;
    int dirty;              /* a parameter changed: the model re-derives its constants */
} FgData;

typedef struct FgInst FgInst;

/* provided by the model */
extern const FgVar FG_VARS[];
extern const int FG_NVARS;
extern const char FG_TOKEN[];   /* instantiationToken */
extern const unsigned FG_SEED_VR;  /* value reference of the Int32 noise seed */
/* extra consistency checks after the range checks; return 0 and call fg_log_error on failure */
int fg_model_check(FgInst *c, const char *fn);
/* states from parameters (called at fmi3ExitInitializationMode), then outputs */
void fg_model_init(FgData *d);
/* advance from d->time by H (sub-steps inside) and set the outputs */
void fg_model_step(FgData *d, double H);

/* provided by the glue */
void fg_log_error(FgInst *c, const char *fmt, ...);
FgData *fg_data(FgInst *c);
double fg_gauss(FgData *d);          /* N(0, 1), seeded, reproducible */

#endif
