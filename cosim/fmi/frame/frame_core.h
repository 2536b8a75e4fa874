/* FMI-version-neutral part of the co-simulation frames (fmi2_frame.c, fmi3_frame.c).
 *
 * One instance = a FrameInstance header (name, mode, time, logging) + the model's
 * plain-old-data block (model_api.h).  The state machine, get/set by value reference
 * with the parameter checks, FMU-state snapshots and doStep live here once; each frame
 * only maps its FMI function signatures onto these and supplies `emit`, which hands a
 * finished log message to its FMI version's logger callback.
 *
 * Status codes are the numeric values shared by fmi2Status and fmi3Status. */
#ifndef DRILLCOSIM_FRAME_CORE_H
#define DRILLCOSIM_FRAME_CORE_H

#include <stddef.h>

#include "model_api.h"

enum { FR_OK = 0, FR_WARNING = 1, FR_DISCARD = 2, FR_ERROR = 3, FR_FATAL = 4 };

typedef enum {
    MODE_INSTANTIATED = 1,
    MODE_INIT = 2,
    MODE_STEP = 4,
    MODE_TERMINATED = 8,
    MODE_ERROR = 16
} Mode;

typedef struct FrameInstance FrameInstance;

/* hand a formatted message to the FMI logger of the frame */
typedef void (*FrameEmit)(FrameInstance *inst, int status, const char *category, const char *msg);

struct FrameInstance {
    char *instanceName;
    int loggingOn;
    Mode mode;
    double time;
    double startTime;
    void *data;        /* MODEL_INFO.data_size bytes */
    FrameEmit emit;
};

/* Allocates `size` >= sizeof(FrameInstance) bytes (a frame may append its callbacks),
 * copies the name, allocates the data block at its defaults; NULL when out of memory. */
FrameInstance *frame_new(size_t size, const char *instanceName, int loggingOn, FrameEmit emit);
void frame_free(FrameInstance *inst);

void frame_log(FrameInstance *inst, int status, const char *category, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
#define FRAME_ERR(inst, ...) frame_log((inst), FR_ERROR, "logStatusError", __VA_ARGS__)

/* 1 when inst is in one of the `allowed` modes, else 0 and an error logged */
int frame_check_mode(FrameInstance *inst, int allowed, const char *fn);

int frame_enter_init(FrameInstance *inst, double startTime, const char *fn);
int frame_exit_init(FrameInstance *inst, const char *fn);
int frame_terminate(FrameInstance *inst, const char *fn);
int frame_reset(FrameInstance *inst);
/* advances inst->time to t + H on success; on failure the instance goes to MODE_ERROR */
int frame_do_step(FrameInstance *inst, double t, double H, const char *fn);

/* Get/set by value reference.  Real (Float64) value references are 1..n_reals;
 * Integer value references are int_vr_base + 1..n_ints (0 in FMI 2.0, n_reals in 3.0,
 * where value references are unique over all types).  With `time_vr` >= 0 that value
 * reference reads the current time (the FMI 3.0 independent variable). */
int frame_get_real(FrameInstance *inst, const unsigned int vr[], size_t nvr, double value[],
                   long time_vr, const char *fn);
int frame_set_real(FrameInstance *inst, const unsigned int vr[], size_t nvr, const double value[],
                   const char *fn);
int frame_get_int(FrameInstance *inst, const unsigned int vr[], size_t nvr, int value[],
                  unsigned int int_vr_base, const char *fn);
int frame_set_int(FrameInstance *inst, const unsigned int vr[], size_t nvr, const int value[],
                  unsigned int int_vr_base, const char *fn);
/* a type this model has no variables of: OK for nvr == 0, else error naming vr[0] */
int frame_no_such_vr(FrameInstance *inst, const unsigned int vr[], size_t nvr, const char *fn);
/* a function this FMU does not provide: error with a message */
int frame_unsupported(FrameInstance *inst, const char *fn);

/* FMU state: a snapshot of mode, time and the whole data block */
size_t frame_state_size(void);
int frame_get_state(FrameInstance *inst, void **state, const char *fn);
int frame_set_state(FrameInstance *inst, const void *state, const char *fn);
void frame_free_state(void **state);
int frame_serialize_state(FrameInstance *inst, const void *state, unsigned char buf[], size_t size,
                          const char *fn);
int frame_deserialize_state(FrameInstance *inst, const unsigned char buf[], size_t size, void **state,
                            const char *fn);

#endif
