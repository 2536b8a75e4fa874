/* Generic FMI 2.0 co-simulation frame shared by the drillcosim plant FMUs.
 *
 * The model (see model_api.h) owns a plain-old-data block (parameters, inputs, outputs,
 * states, noise generator); frame_core.c implements the state machine, get/set by value
 * reference, parameter checks and FMU states around it once for FMI 2.0 and 3.0.  This
 * file maps the FMI 2.0 functions onto it and logs through the fmi2 logger callback.
 * Real and Integer value references are numbered separately from 1. */
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "frame_core.h"

typedef struct {
    FrameInstance core;      /* first: an Instance* is a FrameInstance* */
    fmi2CallbackFunctions cb;
} Instance;

#define CORE(c) ((FrameInstance *)(c))

/* The fmi2 logger takes the message as a format string: escape '%' so that both a
 * formatting logger and a plain one print it unchanged. */
static void emit2(FrameInstance *fi, int status, const char *category, const char *msg)
{
    Instance *inst = (Instance *)fi;
    char esc[2100];
    size_t i, j = 0;
    if (!inst->cb.logger) return;
    for (i = 0; msg[i] && j < sizeof esc - 3; i++) {
        esc[j++] = msg[i];
        if (msg[i] == '%') esc[j++] = '%';
    }
    esc[j] = 0;
    inst->cb.logger(inst->cb.componentEnvironment, fi->instanceName, (fmi2Status)status, category, esc);
}

/* ----------------------------------------------------------------------- common */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    (void)nCategories; (void)categories;
    if (!c) return fmi2Error;
    CORE(c)->loggingOn = loggingOn;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn)
{
    Instance *inst;
    const char *problem = NULL;
    (void)fmuResourceLocation; (void)visible;
    if (!functions || !functions->logger) return NULL;
    if (!instanceName || !instanceName[0]) problem = "fmi2Instantiate: missing instance name";
    else if (fmuType != fmi2CoSimulation) problem = "fmi2Instantiate: only co-simulation is supported";
    else if (fmuGUID && strcmp(fmuGUID, MODEL_INFO.guid) != 0) problem = "fmi2Instantiate: wrong GUID";
    if (problem) {
        functions->logger(functions->componentEnvironment, instanceName && instanceName[0] ? instanceName : "?",
                          fmi2Error, "logStatusError", problem);
        return NULL;
    }
    inst = (Instance *)frame_new(sizeof(Instance), instanceName, loggingOn, emit2);
    if (!inst) return NULL;
    inst->cb = *functions;
    return inst;
}

void fmi2FreeInstance(fmi2Component c) { frame_free(CORE(c)); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (!frame_check_mode(CORE(c), MODE_INSTANTIATED, "fmi2SetupExperiment")) return fmi2Error;
    CORE(c)->startTime = CORE(c)->time = startTime;
#ifdef FRAME_MODEL_STOP_TIME    /* a model that mirrors its master's last communication point */
    model_stop_time(CORE(c)->data, stopTimeDefined ? stopTime : INFINITY);
#endif
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    if (!c) return fmi2Error;
    return (fmi2Status)frame_enter_init(CORE(c), CORE(c)->startTime, "fmi2EnterInitializationMode");
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    return (fmi2Status)frame_exit_init(CORE(c), "fmi2ExitInitializationMode");
}

fmi2Status fmi2Terminate(fmi2Component c) { return (fmi2Status)frame_terminate(CORE(c), "fmi2Terminate"); }
fmi2Status fmi2Reset(fmi2Component c) { return (fmi2Status)frame_reset(CORE(c)); }

/* ----------------------------------------------------------------------- get / set */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    return (fmi2Status)frame_get_real(CORE(c), vr, nvr, value, -1, "fmi2GetReal");
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    return (fmi2Status)frame_set_real(CORE(c), vr, nvr, value, "fmi2SetReal");
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    return (fmi2Status)frame_get_int(CORE(c), vr, nvr, value, 0, "fmi2GetInteger");
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    return (fmi2Status)frame_set_int(CORE(c), vr, nvr, value, 0, "fmi2SetInteger");
}

#define NO_VARS_OF_TYPE(fn, T, CONST)                                                         \
    fmi2Status fn(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, CONST T value[]) \
    {                                                                                         \
        (void)value;                                                                          \
        return (fmi2Status)frame_no_such_vr(CORE(c), vr, nvr, #fn);                           \
    }
NO_VARS_OF_TYPE(fmi2GetBoolean, fmi2Boolean, )
NO_VARS_OF_TYPE(fmi2GetString, fmi2String, )
NO_VARS_OF_TYPE(fmi2SetBoolean, fmi2Boolean, const)
NO_VARS_OF_TYPE(fmi2SetString, fmi2String, const)

/* ----------------------------------------------------------------------- FMU state */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    return (fmi2Status)frame_get_state(CORE(c), FMUstate, "fmi2GetFMUstate");
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    return (fmi2Status)frame_set_state(CORE(c), FMUstate, "fmi2SetFMUstate");
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    (void)c;
    frame_free_state(FMUstate);
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    (void)c; (void)FMUstate;
    *size = frame_state_size();
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size)
{
    return (fmi2Status)frame_serialize_state(CORE(c), FMUstate, (unsigned char *)serializedState, size,
                                             "fmi2SerializeFMUstate");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    return (fmi2Status)frame_deserialize_state(CORE(c), (const unsigned char *)serializedState, size,
                                               FMUstate, "fmi2DeSerializeFMUstate");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    return (fmi2Status)frame_unsupported(CORE(c), "fmi2GetDirectionalDerivative");
}

/* ----------------------------------------------------------------------- co-simulation */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    return (fmi2Status)frame_unsupported(CORE(c), "fmi2SetRealInputDerivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    (void)vr; (void)nvr; (void)order; (void)value;
    return (fmi2Status)frame_unsupported(CORE(c), "fmi2GetRealOutputDerivatives");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    return (fmi2Status)frame_do_step(CORE(c), currentCommunicationPoint, communicationStepSize, "fmi2DoStep");
}

fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    if (c && s == fmi2LastSuccessfulTime) { *value = CORE(c)->time; return fmi2OK; }
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
