/* FMI-version-neutral part of the co-simulation frames: see frame_core.h. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "frame_core.h"

/* ----------------------------------------------------------------------- life cycle */

FrameInstance *frame_new(size_t size, const char *instanceName, int loggingOn, FrameEmit emit)
{
    FrameInstance *inst;
    if (size < sizeof(FrameInstance)) return NULL;
    inst = (FrameInstance *)calloc(1, size);
    if (!inst) return NULL;
    inst->instanceName = (char *)malloc(strlen(instanceName) + 1);
    inst->data = calloc(1, MODEL_INFO.data_size);
    if (!inst->instanceName || !inst->data) {
        free(inst->instanceName); free(inst->data); free(inst);
        return NULL;
    }
    strcpy(inst->instanceName, instanceName);
    inst->loggingOn = loggingOn;
    inst->emit = emit;
    inst->mode = MODE_INSTANTIATED;
    model_set_defaults(inst->data);
    return inst;
}

void frame_free(FrameInstance *inst)
{
    if (!inst) return;
    free(inst->data);
    free(inst->instanceName);
    free(inst);
}

/* ----------------------------------------------------------------------- logging */

void frame_log(FrameInstance *inst, int status, const char *category, const char *fmt, ...)
{
    char buf[1024];
    va_list ap;
    if (!inst || !inst->emit) return;
    if (status == FR_OK && !inst->loggingOn) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    inst->emit(inst, status, category, buf);
}

int frame_check_mode(FrameInstance *inst, int allowed, const char *fn)
{
    if (!inst) return 0;
    if (!(inst->mode & allowed)) {
        FRAME_ERR(inst, "%s: not allowed in the current state (%d)", fn, (int)inst->mode);
        return 0;
    }
    return 1;
}

int frame_unsupported(FrameInstance *inst, const char *fn)
{
    FRAME_ERR(inst, "%s: not provided by this FMU", fn);
    return FR_ERROR;
}

/* ----------------------------------------------------------------------- state machine */

int frame_enter_init(FrameInstance *inst, double startTime, const char *fn)
{
    char msg[512];
    if (!frame_check_mode(inst, MODE_INSTANTIATED, fn)) return FR_ERROR;
    inst->startTime = inst->time = startTime;
    inst->mode = MODE_INIT;
    /* outputs readable during initialisation when the parameters are already valid */
    if (model_validate(inst->data, msg, sizeof msg) == 0) model_initialize(inst->data, inst->startTime);
    return FR_OK;
}

int frame_exit_init(FrameInstance *inst, const char *fn)
{
    char msg[512];
    if (!frame_check_mode(inst, MODE_INIT, fn)) return FR_ERROR;
    msg[0] = 0;
    if (model_validate(inst->data, msg, sizeof msg) != 0) {
        FRAME_ERR(inst, "%s: %s", fn, msg);
        inst->mode = MODE_ERROR;
        return FR_ERROR;
    }
    model_initialize(inst->data, inst->startTime);
    inst->time = inst->startTime;
    inst->mode = MODE_STEP;
    return FR_OK;
}

int frame_terminate(FrameInstance *inst, const char *fn)
{
    if (!frame_check_mode(inst, MODE_STEP | MODE_INIT, fn)) return FR_ERROR;
    inst->mode = MODE_TERMINATED;
    return FR_OK;
}

int frame_reset(FrameInstance *inst)
{
    if (!inst) return FR_ERROR;
    memset(inst->data, 0, MODEL_INFO.data_size);
    model_set_defaults(inst->data);
    inst->mode = MODE_INSTANTIATED;
    inst->time = inst->startTime = 0.0;
    return FR_OK;
}

int frame_do_step(FrameInstance *inst, double t, double H, const char *fn)
{
    char msg[512];
    if (!frame_check_mode(inst, MODE_STEP, fn)) return FR_ERROR;
    if (!(H >= 0.0) || !isfinite(H)) {
        FRAME_ERR(inst, "%s: communicationStepSize = %g, expected a finite value >= 0", fn, H);
        return FR_ERROR;
    }
    msg[0] = 0;
    if (model_do_step(inst->data, t, H, msg, sizeof msg) != 0) {
        FRAME_ERR(inst, "%s at t = %.9g: %s", fn, t, msg);
        inst->mode = MODE_ERROR;
        return FR_ERROR;
    }
    inst->time = t + H;
    return FR_OK;
}

/* ----------------------------------------------------------------------- get / set */

static const VarInfo *find_var(FrameInstance *inst, const VarInfo *table, size_t n, unsigned int vr,
                               unsigned int base, const char *fn)
{
    if (vr <= base || vr - base > n) {
        FRAME_ERR(inst, "%s: unknown value reference %u", fn, vr);
        return NULL;
    }
    return &table[vr - base - 1];
}

/* An FMU exported from a drillcosim block (cosim/exchange/export_fmu.py) passes NaN ("not yet",
 * e.g. a detection time) through its inputs as the block does; the plants refuse it. */
#ifndef FRAME_NONFINITE_INPUTS
#define FRAME_NONFINITE_INPUTS 0
#endif

#define VALUE_PTR(inst, v, T) ((T *)((char *)(inst)->data + (v)->offset))

int frame_get_real(FrameInstance *inst, const unsigned int vr[], size_t nvr, double value[],
                   long time_vr, const char *fn)
{
    size_t i;
    if (!inst || inst->mode == MODE_ERROR) return FR_ERROR;
    for (i = 0; i < nvr; i++) {
        const VarInfo *v;
        if (time_vr >= 0 && vr[i] == (unsigned long)time_vr) { value[i] = inst->time; continue; }
        v = find_var(inst, MODEL_INFO.reals, MODEL_INFO.n_reals, vr[i], 0, fn);
        if (!v) return FR_ERROR;
        value[i] = *VALUE_PTR(inst, v, double);
    }
    return FR_OK;
}

int frame_get_int(FrameInstance *inst, const unsigned int vr[], size_t nvr, int value[],
                  unsigned int int_vr_base, const char *fn)
{
    size_t i;
    if (!inst || inst->mode == MODE_ERROR) return FR_ERROR;
    for (i = 0; i < nvr; i++) {
        const VarInfo *v = find_var(inst, MODEL_INFO.ints, MODEL_INFO.n_ints, vr[i], int_vr_base, fn);
        if (!v) return FR_ERROR;
        value[i] = *VALUE_PTR(inst, v, int);
    }
    return FR_OK;
}

/* Checks whether variable v may be set now; in step mode only inputs and tunable parameters. */
static int settable(FrameInstance *inst, const VarInfo *v, const char *fn)
{
    if (v->causality == CAUS_OUTPUT) {
        FRAME_ERR(inst, "%s: %s is an output and cannot be set", fn, v->name);
        return 0;
    }
    if (inst->mode & (MODE_INSTANTIATED | MODE_INIT)) return 1;
    if (inst->mode == MODE_STEP) {
        if (v->causality == CAUS_INPUT || v->variability == VAR_TUNABLE) return 1;
        FRAME_ERR(inst, "%s: parameter %s is fixed and cannot be changed after initialisation", fn, v->name);
        return 0;
    }
    FRAME_ERR(inst, "%s: not allowed in the current state (%d)", fn, (int)inst->mode);
    return 0;
}

int frame_set_real(FrameInstance *inst, const unsigned int vr[], size_t nvr, const double value[],
                   const char *fn)
{
    size_t i;
    int tunable_changed = 0;
    void *backup = NULL;
    char msg[512];
    if (!inst) return FR_ERROR;
    if (inst->mode == MODE_STEP) {
        for (i = 0; i < nvr; i++)
            if (vr[i] >= 1 && vr[i] <= MODEL_INFO.n_reals &&
                MODEL_INFO.reals[vr[i] - 1].causality == CAUS_PARAMETER) tunable_changed = 1;
        if (tunable_changed) {
            backup = malloc(MODEL_INFO.data_size);
            if (!backup) return FR_ERROR;
            memcpy(backup, inst->data, MODEL_INFO.data_size);
        }
    }
    for (i = 0; i < nvr; i++) {
        const VarInfo *v = find_var(inst, MODEL_INFO.reals, MODEL_INFO.n_reals, vr[i], 0, fn);
        if (!v || !settable(inst, v, fn)) goto fail;
        if (!isfinite(value[i]) && !(FRAME_NONFINITE_INPUTS && v->causality == CAUS_INPUT)) {
            FRAME_ERR(inst, "%s: %s = %g is not a finite number", fn, v->name, value[i]);
            goto fail;
        }
        *VALUE_PTR(inst, v, double) = value[i];
    }
    if (tunable_changed && model_validate(inst->data, msg, sizeof msg) != 0) {
        FRAME_ERR(inst, "%s: %s", fn, msg);
        goto fail;
    }
    free(backup);
    return FR_OK;
fail:
    if (backup) {
        memcpy(inst->data, backup, MODEL_INFO.data_size);
        free(backup);
    }
    return FR_ERROR;
}

int frame_set_int(FrameInstance *inst, const unsigned int vr[], size_t nvr, const int value[],
                  unsigned int int_vr_base, const char *fn)
{
    size_t i;
    if (!inst) return FR_ERROR;
    for (i = 0; i < nvr; i++) {
        const VarInfo *v = find_var(inst, MODEL_INFO.ints, MODEL_INFO.n_ints, vr[i], int_vr_base, fn);
        if (!v || !settable(inst, v, fn)) return FR_ERROR;
        *VALUE_PTR(inst, v, int) = value[i];
    }
    return FR_OK;
}

int frame_no_such_vr(FrameInstance *inst, const unsigned int vr[], size_t nvr, const char *fn)
{
    if (nvr == 0) return FR_OK;
    FRAME_ERR(inst, "%s: unknown value reference %u", fn, vr[0]);
    return FR_ERROR;
}

/* ----------------------------------------------------------------------- FMU state */

typedef struct {
    unsigned int magic;
    Mode mode;
    double time, startTime;
    unsigned char data[]; /* MODEL_INFO.data_size */
} Snapshot;

#define SNAP_MAGIC 0xD7111C05u

size_t frame_state_size(void) { return sizeof(Snapshot) + MODEL_INFO.data_size; }

int frame_get_state(FrameInstance *inst, void **state, const char *fn)
{
    Snapshot *s;
    if (!inst || !state) return FR_ERROR;
    s = (Snapshot *)(*state);
    if (!s) {
        s = (Snapshot *)malloc(frame_state_size());
        if (!s) { FRAME_ERR(inst, "%s: out of memory", fn); return FR_ERROR; }
    }
    s->magic = SNAP_MAGIC;
    s->mode = inst->mode;
    s->time = inst->time;
    s->startTime = inst->startTime;
    memcpy(s->data, inst->data, MODEL_INFO.data_size);
    *state = s;
    return FR_OK;
}

int frame_set_state(FrameInstance *inst, const void *state, const char *fn)
{
    const Snapshot *s = (const Snapshot *)state;
    if (!inst) return FR_ERROR;
    if (!s || s->magic != SNAP_MAGIC) { FRAME_ERR(inst, "%s: invalid state", fn); return FR_ERROR; }
    inst->mode = s->mode;
    inst->time = s->time;
    inst->startTime = s->startTime;
    memcpy(inst->data, s->data, MODEL_INFO.data_size);
    return FR_OK;
}

void frame_free_state(void **state)
{
    if (state && *state) {
        free(*state);
        *state = NULL;
    }
}

int frame_serialize_state(FrameInstance *inst, const void *state, unsigned char buf[], size_t size,
                          const char *fn)
{
    if (!state || size < frame_state_size()) { FRAME_ERR(inst, "%s: buffer too small", fn); return FR_ERROR; }
    memcpy(buf, state, frame_state_size());
    return FR_OK;
}

int frame_deserialize_state(FrameInstance *inst, const unsigned char buf[], size_t size, void **state,
                            const char *fn)
{
    Snapshot *s;
    if (size != frame_state_size() || ((const Snapshot *)buf)->magic != SNAP_MAGIC) {
        FRAME_ERR(inst, "%s: the serialized state does not belong to this FMU", fn);
        return FR_ERROR;
    }
    s = (Snapshot *)malloc(size);
    if (!s) return FR_ERROR;
    memcpy(s, buf, size);
    *state = s;
    return FR_OK;
}
