/* Generic FMI 2.0 co-simulation frame shared by the drillcosim plant FMUs.
 *
 * The model (see model_api.h) owns a plain-old-data block (parameters, inputs, outputs,
 * states, noise generator); this file implements the FMI functions around it:
 * state machine, get/set by value reference, logging through the logger callback,
 * fmi2Get/Set/FreeFMUstate and (de)serialisation by copying the data block. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "model_api.h"

typedef enum {
    MODE_INSTANTIATED = 1,
    MODE_INIT = 2,
    MODE_STEP = 4,
    MODE_TERMINATED = 8,
    MODE_ERROR = 16
} Mode;

typedef struct {
    char *instanceName;
    fmi2CallbackFunctions cb;
    fmi2Boolean loggingOn;
    Mode mode;
    double time;
    double startTime;
    void *data; /* MODEL_INFO.data_size bytes */
} Instance;

/* ----------------------------------------------------------------------- logging */

static void log_msg(Instance *inst, fmi2Status status, const char *category, const char *fmt, ...)
{
    char buf[1024], esc[2100];
    va_list ap;
    size_t i, j = 0;
    if (!inst || !inst->cb.logger) return;
    if (status == fmi2OK && !inst->loggingOn) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    /* the message is passed as the format string: escape '%' so that both a formatting
     * logger and a plain one print it unchanged */
    for (i = 0; buf[i] && j < sizeof esc - 3; i++) {
        esc[j++] = buf[i];
        if (buf[i] == '%') esc[j++] = '%';
    }
    esc[j] = 0;
    inst->cb.logger(inst->cb.componentEnvironment, inst->instanceName, status, category, esc);
}

#define ERR(inst, ...) log_msg((inst), fmi2Error, "logStatusError", __VA_ARGS__)

static int check_mode(Instance *inst, int allowed, const char *fn)
{
    if (!inst) return 0;
    if (!(inst->mode & allowed)) {
        ERR(inst, "%s: not allowed in the current state (%d)", fn, (int)inst->mode);
        return 0;
    }
    return 1;
}

/* ----------------------------------------------------------------------- common */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    Instance *inst = (Instance *)c;
    (void)nCategories; (void)categories;
    if (!inst) return fmi2Error;
    inst->loggingOn = loggingOn;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn)
{
    Instance *inst;
    (void)fmuResourceLocation; (void)visible;
    if (!functions || !functions->logger) return NULL;
    if (!instanceName || !instanceName[0]) {
        functions->logger(functions->componentEnvironment, "?", fmi2Error, "logStatusError",
                          "fmi2Instantiate: missing instance name");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        functions->logger(functions->componentEnvironment, instanceName, fmi2Error,
                          "logStatusError", "fmi2Instantiate: only co-simulation is supported");
        return NULL;
    }
    if (fmuGUID && strcmp(fmuGUID, MODEL_INFO.guid) != 0) {
        functions->logger(functions->componentEnvironment, instanceName, fmi2Error,
                          "logStatusError", "fmi2Instantiate: wrong GUID");
        return NULL;
    }
    inst = (Instance *)calloc(1, sizeof(Instance));
    if (!inst) return NULL;
    inst->instanceName = (char *)malloc(strlen(instanceName) + 1);
    inst->data = calloc(1, MODEL_INFO.data_size);
    if (!inst->instanceName || !inst->data) {
        free(inst->instanceName); free(inst->data); free(inst);
        return NULL;
    }
    strcpy(inst->instanceName, instanceName);
    inst->cb = *functions;
    inst->loggingOn = loggingOn;
    inst->mode = MODE_INSTANTIATED;
    model_set_defaults(inst->data);
    return inst;
}

void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    if (!inst) return;
    free(inst->data);
    free(inst->instanceName);
    free(inst);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    Instance *inst = (Instance *)c;
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (!check_mode(inst, MODE_INSTANTIATED, "fmi2SetupExperiment")) return fmi2Error;
    inst->startTime = startTime;
    inst->time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    char msg[512];
    if (!check_mode(inst, MODE_INSTANTIATED, "fmi2EnterInitializationMode")) return fmi2Error;
    inst->mode = MODE_INIT;
    /* outputs readable during initialisation when the parameters are already valid */
    if (model_validate(inst->data, msg, sizeof msg) == 0) model_initialize(inst->data, inst->startTime);
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    char msg[512];
    if (!check_mode(inst, MODE_INIT, "fmi2ExitInitializationMode")) return fmi2Error;
    msg[0] = 0;
    if (model_validate(inst->data, msg, sizeof msg) != 0) {
        ERR(inst, "fmi2ExitInitializationMode: %s", msg);
        inst->mode = MODE_ERROR;
        return fmi2Error;
    }
    model_initialize(inst->data, inst->startTime);
    inst->time = inst->startTime;
    inst->mode = MODE_STEP;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    if (!check_mode(inst, MODE_STEP | MODE_INIT, "fmi2Terminate")) return fmi2Error;
    inst->mode = MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    if (!inst) return fmi2Error;
    memset(inst->data, 0, MODEL_INFO.data_size);
    model_set_defaults(inst->data);
    inst->mode = MODE_INSTANTIATED;
    inst->time = inst->startTime = 0.0;
    return fmi2OK;
}

/* ----------------------------------------------------------------------- get / set */

static const VarInfo *find_var(Instance *inst, const VarInfo *table, size_t n, fmi2ValueReference vr,
                               const char *fn)
{
    if (vr < 1 || vr > n) {
        ERR(inst, "%s: unknown value reference %u", fn, (unsigned)vr);
        return NULL;
    }
    return &table[vr - 1];
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    Instance *inst = (Instance *)c;
    size_t i;
    if (!inst) return fmi2Error;
    if (inst->mode == MODE_ERROR) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        const VarInfo *v;
        if (vr[i] < 1 || vr[i] > MODEL_INFO.n_reals) {
            ERR(inst, "fmi2GetReal: unknown value reference %u", (unsigned)vr[i]);
            return fmi2Error;
        }
        v = &MODEL_INFO.reals[vr[i] - 1];
        value[i] = *(const double *)((const char *)inst->data + v->offset);
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    Instance *inst = (Instance *)c;
    size_t i;
    if (!inst) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        const VarInfo *v = find_var(inst, MODEL_INFO.ints, MODEL_INFO.n_ints, vr[i], "fmi2GetInteger");
        if (!v) return fmi2Error;
        value[i] = *(const int *)((const char *)inst->data + v->offset);
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    (void)value;
    if (nvr == 0) return fmi2OK;
    ERR((Instance *)c, "fmi2GetBoolean: unknown value reference %u", (unsigned)vr[0]);
    return fmi2Error;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    (void)value;
    if (nvr == 0) return fmi2OK;
    ERR((Instance *)c, "fmi2GetString: unknown value reference %u", (unsigned)vr[0]);
    return fmi2Error;
}

/* Checks whether variable v may be set now; in step mode only inputs and tunable parameters. */
static int settable(Instance *inst, const VarInfo *v, const char *fn)
{
    if (v->causality == CAUS_OUTPUT) {
        ERR(inst, "%s: %s is an output and cannot be set", fn, v->name);
        return 0;
    }
    if (inst->mode & (MODE_INSTANTIATED | MODE_INIT)) return 1;
    if (inst->mode == MODE_STEP) {
        if (v->causality == CAUS_INPUT || v->variability == VAR_TUNABLE) return 1;
        ERR(inst, "%s: parameter %s is fixed and cannot be changed after initialisation", fn, v->name);
        return 0;
    }
    ERR(inst, "%s: not allowed in the current state (%d)", fn, (int)inst->mode);
    return 0;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    Instance *inst = (Instance *)c;
    size_t i;
    int tunable_changed = 0;
    void *backup = NULL;
    char msg[512];
    if (!inst) return fmi2Error;
    if (inst->mode == MODE_STEP) {
        for (i = 0; i < nvr; i++)
            if (vr[i] >= 1 && vr[i] <= MODEL_INFO.n_reals &&
                MODEL_INFO.reals[vr[i] - 1].causality == CAUS_PARAMETER) tunable_changed = 1;
        if (tunable_changed) {
            backup = malloc(MODEL_INFO.data_size);
            if (!backup) return fmi2Error;
            memcpy(backup, inst->data, MODEL_INFO.data_size);
        }
    }
    for (i = 0; i < nvr; i++) {
        const VarInfo *v = find_var(inst, MODEL_INFO.reals, MODEL_INFO.n_reals, vr[i], "fmi2SetReal");
        if (!v || !settable(inst, v, "fmi2SetReal")) goto fail;
        if (!isfinite(value[i])) {
            ERR(inst, "fmi2SetReal: %s = %g is not a finite number", v->name, value[i]);
            goto fail;
        }
        *(double *)((char *)inst->data + v->offset) = value[i];
    }
    if (tunable_changed && model_validate(inst->data, msg, sizeof msg) != 0) {
        ERR(inst, "fmi2SetReal: %s", msg);
        goto fail;
    }
    free(backup);
    return fmi2OK;
fail:
    if (backup) {
        memcpy(inst->data, backup, MODEL_INFO.data_size);
        free(backup);
    }
    return fmi2Error;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    Instance *inst = (Instance *)c;
    size_t i;
    if (!inst) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        const VarInfo *v = find_var(inst, MODEL_INFO.ints, MODEL_INFO.n_ints, vr[i], "fmi2SetInteger");
        if (!v || !settable(inst, v, "fmi2SetInteger")) return fmi2Error;
        *(int *)((char *)inst->data + v->offset) = value[i];
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
{
    (void)value;
    if (nvr == 0) return fmi2OK;
    ERR((Instance *)c, "fmi2SetBoolean: unknown value reference %u", (unsigned)vr[0]);
    return fmi2Error;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    (void)value;
    if (nvr == 0) return fmi2OK;
    ERR((Instance *)c, "fmi2SetString: unknown value reference %u", (unsigned)vr[0]);
    return fmi2Error;
}

/* ----------------------------------------------------------------------- FMU state */

typedef struct {
    unsigned int magic;
    Mode mode;
    double time, startTime;
    unsigned char data[]; /* MODEL_INFO.data_size */
} Snapshot;

#define SNAP_MAGIC 0xD7111C05u

static size_t snap_size(void) { return sizeof(Snapshot) + MODEL_INFO.data_size; }

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    Instance *inst = (Instance *)c;
    Snapshot *s;
    if (!inst || !FMUstate) return fmi2Error;
    s = (Snapshot *)(*FMUstate);
    if (!s) {
        s = (Snapshot *)malloc(snap_size());
        if (!s) { ERR(inst, "fmi2GetFMUstate: out of memory"); return fmi2Error; }
    }
    s->magic = SNAP_MAGIC;
    s->mode = inst->mode;
    s->time = inst->time;
    s->startTime = inst->startTime;
    memcpy(s->data, inst->data, MODEL_INFO.data_size);
    *FMUstate = s;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    Instance *inst = (Instance *)c;
    const Snapshot *s = (const Snapshot *)FMUstate;
    if (!inst) return fmi2Error;
    if (!s || s->magic != SNAP_MAGIC) { ERR(inst, "fmi2SetFMUstate: invalid state"); return fmi2Error; }
    inst->mode = s->mode;
    inst->time = s->time;
    inst->startTime = s->startTime;
    memcpy(inst->data, s->data, MODEL_INFO.data_size);
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    (void)c;
    if (FMUstate && *FMUstate) {
        free(*FMUstate);
        *FMUstate = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    (void)c; (void)FMUstate;
    *size = snap_size();
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size)
{
    Instance *inst = (Instance *)c;
    if (!FMUstate || size < snap_size()) { ERR(inst, "fmi2SerializeFMUstate: buffer too small"); return fmi2Error; }
    memcpy(serializedState, FMUstate, snap_size());
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    Instance *inst = (Instance *)c;
    Snapshot *s;
    if (size != snap_size() || ((const Snapshot *)serializedState)->magic != SNAP_MAGIC) {
        ERR(inst, "fmi2DeSerializeFMUstate: the serialized state does not belong to this FMU");
        return fmi2Error;
    }
    s = (Snapshot *)malloc(size);
    if (!s) return fmi2Error;
    memcpy(s, serializedState, size);
    *FMUstate = s;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    ERR((Instance *)c, "fmi2GetDirectionalDerivative: not provided");
    return fmi2Error;
}

/* ----------------------------------------------------------------------- co-simulation */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    ERR((Instance *)c, "fmi2SetRealInputDerivatives: not supported");
    return fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    ERR((Instance *)c, "fmi2GetRealOutputDerivatives: not supported");
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Instance *inst = (Instance *)c;
    char msg[512];
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!inst) return fmi2Error;
    if (inst->mode != MODE_STEP) {
        ERR(inst, "fmi2DoStep: not allowed in the current state (%d)", (int)inst->mode);
        return fmi2Error;
    }
    if (!(communicationStepSize >= 0.0) || !isfinite(communicationStepSize)) {
        ERR(inst, "fmi2DoStep: communicationStepSize = %g, expected a finite value >= 0",
            communicationStepSize);
        return fmi2Error;
    }
    msg[0] = 0;
    if (model_do_step(inst->data, currentCommunicationPoint, communicationStepSize, msg, sizeof msg) != 0) {
        ERR(inst, "fmi2DoStep at t = %.9g: %s", currentCommunicationPoint, msg);
        inst->mode = MODE_ERROR;
        return fmi2Error;
    }
    inst->time = currentCommunicationPoint + communicationStepSize;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    Instance *inst = (Instance *)c;
    if (inst && s == fmi2LastSuccessfulTime) { *value = inst->time; return fmi2OK; }
    return fmi2Discard;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

/* ----------------------------------------------------------------------- model exchange (not supported) */

fmi2Status fmi2EnterEventMode(fmi2Component c) { (void)c; return fmi2Error; }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *e) { (void)c; (void)e; return fmi2Error; }
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { (void)c; return fmi2Error; }
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean n, fmi2Boolean *e, fmi2Boolean *t)
{ (void)c; (void)n; (void)e; (void)t; return fmi2Error; }
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) { (void)c; (void)t; return fmi2Error; }
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx)
{ (void)c; (void)x; (void)nx; return fmi2Error; }
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real d[], size_t nx) { (void)c; (void)d; (void)nx; return fmi2Error; }
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real e[], size_t ni) { (void)c; (void)e; (void)ni; return fmi2Error; }
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) { (void)c; (void)x; (void)nx; return fmi2Error; }
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t nx)
{ (void)c; (void)x; (void)nx; return fmi2Error; }
