/* Interface between the generic FMI 2.0 co-simulation frame (fmi2_frame.c) and a plant
 * model (LinearStage.c, BallScrewDrive.c).  The model provides MODEL_INFO and the
 * model_* hooks; the frame does the FMI state machine, get/set, logging and FMU states. */
#ifndef DRILLCOSIM_MODEL_API_H
#define DRILLCOSIM_MODEL_API_H

#include <stddef.h>

enum { CAUS_PARAMETER = 0, CAUS_INPUT = 1, CAUS_OUTPUT = 2 };
enum { VAR_FIXED = 0, VAR_TUNABLE = 1, VAR_CONTINUOUS = 2 };

typedef struct {
    const char *name;
    unsigned int vr;
    size_t offset;      /* byte offset of the value inside the model data block */
    int causality;
    int variability;
    double start;       /* default (also used for Integer variables) */
} VarInfo;

typedef struct {
    const char *name;          /* modelIdentifier */
    const char *guid;
    const VarInfo *reals;      /* indexed by vr - 1 */
    size_t n_reals;
    const VarInfo *ints;       /* indexed by vr - 1 */
    size_t n_ints;
    size_t data_size;          /* sizeof the model data block (plain old data) */
} ModelInfo;

extern const ModelInfo MODEL_INFO;

/* In a model file, after its <Model>_vars.h (MODEL_NAME, MODEL_GUID, MODEL_REAL_VARS,
 * MODEL_INT_VARS) and the definition of its data block type:
 *
 *   MODEL_INFO_DEFINE(ModelData);              -- defines MODEL_INFO
 *   void model_set_defaults(void *data) {
 *       MODEL_SET_START_VALUES(data);          -- every variable at its start value
 *       ... the model's own initial states ...
 *   }
 */
#define MODEL_INFO_DEFINE(DataType)                                                    \
    const ModelInfo MODEL_INFO = {                                                     \
        MODEL_NAME, MODEL_GUID,                                                        \
        MODEL_REAL_VARS, sizeof(MODEL_REAL_VARS) / sizeof(MODEL_REAL_VARS[0]),         \
        MODEL_INT_VARS, sizeof(MODEL_INT_VARS) / sizeof(MODEL_INT_VARS[0]),            \
        sizeof(DataType)                                                               \
    }

#define MODEL_SET_START_VALUES(data)                                                   \
    do {                                                                               \
        size_t k_;                                                                     \
        for (k_ = 0; k_ < MODEL_INFO.n_reals; k_++)                                    \
            *(double *)((char *)(data) + MODEL_REAL_VARS[k_].offset) = MODEL_REAL_VARS[k_].start; \
        for (k_ = 0; k_ < MODEL_INFO.n_ints; k_++)                                     \
            *(int *)((char *)(data) + MODEL_INT_VARS[k_].offset) = (int)MODEL_INT_VARS[k_].start; \
    } while (0)

/* Put every variable at its start value (MODEL_SET_START_VALUES) and set the states. */
void model_set_defaults(void *data);
/* Check all parameters; on failure write a message naming the variable and what was
 * expected into msg and return nonzero. */
int model_validate(const void *data, char *msg, size_t n);
/* Set the states from the parameters, seed the noise generator, compute the outputs. */
void model_initialize(void *data, double start_time);
/* Advance by H from t (fixed internal sub-steps); nonzero + message on failure. */
int model_do_step(void *data, double t, double H, char *msg, size_t n);

#endif
