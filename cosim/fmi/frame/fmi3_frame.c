/* Generic FMI 3.0 co-simulation frame shared by the drillcosim plant FMUs.
 *
 * Same model hooks (model_api.h) and the same core (frame_core.c: state machine,
 * get/set, parameter checks, FMU states) as the FMI 2.0 frame; this file maps the
 * FMI 3.0 functions onto them and logs through the fmi3 log-message callback.
 *
 * Value references (unique over all types, as FMI 3.0 requires; generated the same way
 * by fmus/build.py): 0 = time (the independent variable), Float64 1..n_reals (the FMI 2.0
 * Real value references), Int32 n_reals + 1..n_reals + n_ints.  The instantiation token
 * is the model's GUID.  No event mode, no intermediate update, no early return. */
#include <stdint.h>
#include <string.h>

#include "fmi3Functions.h"
#include "frame_core.h"

typedef struct {
    FrameInstance core;      /* first: an Instance* is a FrameInstance* */
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback logMessage;
} Instance;

#define CORE(c) ((FrameInstance *)(c))
#define TIME_VR 0
#define INT_VR_BASE ((unsigned int)MODEL_INFO.n_reals)

static void emit3(FrameInstance *fi, int status, const char *category, const char *msg)
{
    Instance *inst = (Instance *)fi;
    if (inst->logMessage) inst->logMessage(inst->env, (fmi3Status)status, category, msg);
}

/* ----------------------------------------------------------------------- common */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    (void)nCategories; (void)categories;
    if (!instance) return fmi3Error;
    CORE(instance)->loggingOn = loggingOn;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible,
                                         fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
                                         fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    Instance *inst;
    const char *problem = NULL;
    (void)resourcePath; (void)visible; (void)earlyReturnAllowed; (void)intermediateUpdate;
    (void)requiredIntermediateVariables;
    if (!instanceName || !instanceName[0]) problem = "fmi3InstantiateCoSimulation: missing instance name";
    else if (instantiationToken && strcmp(instantiationToken, MODEL_INFO.guid) != 0)
        problem = "fmi3InstantiateCoSimulation: wrong instantiationToken";
    else if (eventModeUsed) problem = "fmi3InstantiateCoSimulation: event mode is not supported (hasEventMode=false)";
    else if (nRequiredIntermediateVariables > 0)
        problem = "fmi3InstantiateCoSimulation: intermediate update is not provided";
    if (problem) {
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", problem);
        return NULL;
    }
    inst = (Instance *)frame_new(sizeof(Instance), instanceName, loggingOn, emit3);
    if (!inst) return NULL;
    inst->env = instanceEnvironment;
    inst->logMessage = logMessage;
    return inst;
}

static void log_not_co_simulation(fmi3InstanceEnvironment env, fmi3LogMessageCallback logMessage,
                                  const char *fn)
{
    if (logMessage)
        logMessage(env, fmi3Error, "logStatusError", fn);
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    log_not_co_simulation(instanceEnvironment, logMessage,
                          "fmi3InstantiateModelExchange: only co-simulation is supported");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible,
                                               fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage,
                                               fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    log_not_co_simulation(instanceEnvironment, logMessage,
                          "fmi3InstantiateScheduledExecution: only co-simulation is supported");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) { frame_free(CORE(instance)); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
#ifdef FRAME_MODEL_STOP_TIME    /* a model that mirrors its master's last communication point */
    if (instance) model_stop_time(CORE(instance)->data, stopTimeDefined ? stopTime : INFINITY);
#endif
    return (fmi3Status)frame_enter_init(CORE(instance), startTime, "fmi3EnterInitializationMode");
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    return (fmi3Status)frame_exit_init(CORE(instance), "fmi3ExitInitializationMode");
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    return (fmi3Status)frame_terminate(CORE(instance), "fmi3Terminate");
}

fmi3Status fmi3Reset(fmi3Instance instance) { return (fmi3Status)frame_reset(CORE(instance)); }

/* ----------------------------------------------------------------------- get / set */

/* scalar variables only: nValues must equal nValueReferences */
static int scalar_counts(fmi3Instance instance, size_t nvr, size_t nValues, const char *fn)
{
    if (nvr == nValues) return 1;
    FRAME_ERR(CORE(instance), "%s: nValues = %zu, expected nValueReferences = %zu (all variables are scalars)",
              fn, nValues, nvr);
    return 0;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues)
{
    if (!instance || !scalar_counts(instance, nValueReferences, nValues, "fmi3GetFloat64")) return fmi3Error;
    return (fmi3Status)frame_get_real(CORE(instance), valueReferences, nValueReferences, values, TIME_VR,
                                      "fmi3GetFloat64");
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[], size_t nValues)
{
    if (!instance || !scalar_counts(instance, nValueReferences, nValues, "fmi3SetFloat64")) return fmi3Error;
    return (fmi3Status)frame_set_real(CORE(instance), valueReferences, nValueReferences, values,
                                      "fmi3SetFloat64");
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Int32 values[], size_t nValues)
{
    if (!instance || !scalar_counts(instance, nValueReferences, nValues, "fmi3GetInt32")) return fmi3Error;
    return (fmi3Status)frame_get_int(CORE(instance), valueReferences, nValueReferences, (int *)values,
                                     INT_VR_BASE, "fmi3GetInt32");
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Int32 values[], size_t nValues)
{
    if (!instance || !scalar_counts(instance, nValueReferences, nValues, "fmi3SetInt32")) return fmi3Error;
    return (fmi3Status)frame_set_int(CORE(instance), valueReferences, nValueReferences, (const int *)values,
                                     INT_VR_BASE, "fmi3SetInt32");
}

/* Types this model has no variables of (Int64 is what importers use for enumerations):
 * OK for an empty request, else an error naming the value reference. */
#define NO_VARS_OF_TYPE(fn, T, CONST)                                                              \
    fmi3Status fn(fmi3Instance instance, const fmi3ValueReference valueReferences[],               \
                  size_t nValueReferences, CONST T values[], size_t nValues)                        \
    {                                                                                              \
        (void)values; (void)nValues;                                                               \
        return (fmi3Status)frame_no_such_vr(CORE(instance), valueReferences, nValueReferences, #fn); \
    }
NO_VARS_OF_TYPE(fmi3GetFloat32, fmi3Float32, )
NO_VARS_OF_TYPE(fmi3GetInt8, fmi3Int8, )
NO_VARS_OF_TYPE(fmi3GetUInt8, fmi3UInt8, )
NO_VARS_OF_TYPE(fmi3GetInt16, fmi3Int16, )
NO_VARS_OF_TYPE(fmi3GetUInt16, fmi3UInt16, )
NO_VARS_OF_TYPE(fmi3GetUInt32, fmi3UInt32, )
NO_VARS_OF_TYPE(fmi3GetInt64, fmi3Int64, )
NO_VARS_OF_TYPE(fmi3GetUInt64, fmi3UInt64, )
NO_VARS_OF_TYPE(fmi3GetBoolean, fmi3Boolean, )
NO_VARS_OF_TYPE(fmi3GetString, fmi3String, )
NO_VARS_OF_TYPE(fmi3SetFloat32, fmi3Float32, const)
NO_VARS_OF_TYPE(fmi3SetInt8, fmi3Int8, const)
NO_VARS_OF_TYPE(fmi3SetUInt8, fmi3UInt8, const)
NO_VARS_OF_TYPE(fmi3SetInt16, fmi3Int16, const)
NO_VARS_OF_TYPE(fmi3SetUInt16, fmi3UInt16, const)
NO_VARS_OF_TYPE(fmi3SetUInt32, fmi3UInt32, const)
NO_VARS_OF_TYPE(fmi3SetInt64, fmi3Int64, const)
NO_VARS_OF_TYPE(fmi3SetUInt64, fmi3UInt64, const)
NO_VARS_OF_TYPE(fmi3SetBoolean, fmi3Boolean, const)
NO_VARS_OF_TYPE(fmi3SetString, fmi3String, const)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, size_t valueSizes[], fmi3Binary values[], size_t nValues)
{
    (void)valueSizes; (void)values; (void)nValues;
    return (fmi3Status)frame_no_such_vr(CORE(instance), valueReferences, nValueReferences, "fmi3GetBinary");
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const size_t valueSizes[], const fmi3Binary values[],
                         size_t nValues)
{
    (void)valueSizes; (void)values; (void)nValues;
    return (fmi3Status)frame_no_such_vr(CORE(instance), valueReferences, nValueReferences, "fmi3SetBinary");
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Clock values[])
{
    (void)values;
    return (fmi3Status)frame_no_such_vr(CORE(instance), valueReferences, nValueReferences, "fmi3GetClock");
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Clock values[])
{
    (void)values;
    return (fmi3Status)frame_no_such_vr(CORE(instance), valueReferences, nValueReferences, "fmi3SetClock");
}

/* ----------------------------------------------------------------------- FMU state */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    return (fmi3Status)frame_get_state(CORE(instance), FMUState, "fmi3GetFMUState");
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState)
{
    return (fmi3Status)frame_set_state(CORE(instance), FMUState, "fmi3SetFMUState");
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    (void)instance;
    frame_free_state(FMUState);
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size)
{
    (void)instance; (void)FMUState;
    *size = frame_state_size();
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size)
{
    return (fmi3Status)frame_serialize_state(CORE(instance), FMUState, serializedState, size,
                                             "fmi3SerializeFMUState");
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState)
{
    return (fmi3Status)frame_deserialize_state(CORE(instance), serializedState, size, FMUState,
                                               "fmi3DeserializeFMUState");
}

/* ----------------------------------------------------------------------- co-simulation */

fmi3Status fmi3EnterStepMode(fmi3Instance instance)
{
    /* without event mode the FMU is in step mode right after initialisation */
    return frame_check_mode(CORE(instance), MODE_STEP, "fmi3EnterStepMode") ? fmi3OK : fmi3Error;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    int status;
    (void)noSetFMUStatePriorToCurrentPoint;
    status = frame_do_step(CORE(instance), currentCommunicationPoint, communicationStepSize, "fmi3DoStep");
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime && instance) *lastSuccessfulTime = CORE(instance)->time;
    return (fmi3Status)status;
}

/* ----------------------------------------------------------------------- not provided
 * (capability flags false in modelDescription.xml; an error naming the function) */

#define UNSUPPORTED(fn, ...)                                              \
    fmi3Status fn(fmi3Instance instance, __VA_ARGS__)                     \
    {                                                                     \
        return (fmi3Status)frame_unsupported(CORE(instance), #fn);        \
    }
#define UNSUPPORTED0(fn)                                                  \
    fmi3Status fn(fmi3Instance instance)                                  \
    {                                                                     \
        return (fmi3Status)frame_unsupported(CORE(instance), #fn);        \
    }

#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter"
#endif
UNSUPPORTED(fmi3GetNumberOfVariableDependencies, fmi3ValueReference valueReference, size_t *nDependencies)
UNSUPPORTED(fmi3GetVariableDependencies, fmi3ValueReference dependent, size_t elementIndicesOfDependent[],
            fmi3ValueReference independents[], size_t elementIndicesOfIndependents[],
            fmi3DependencyKind dependencyKinds[], size_t nDependencies)
UNSUPPORTED(fmi3GetDirectionalDerivative, const fmi3ValueReference unknowns[], size_t nUnknowns,
            const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
            fmi3Float64 sensitivity[], size_t nSensitivity)
UNSUPPORTED(fmi3GetAdjointDerivative, const fmi3ValueReference unknowns[], size_t nUnknowns,
            const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
            fmi3Float64 sensitivity[], size_t nSensitivity)
UNSUPPORTED0(fmi3EnterConfigurationMode)
UNSUPPORTED0(fmi3ExitConfigurationMode)
UNSUPPORTED(fmi3GetIntervalDecimal, const fmi3ValueReference valueReferences[], size_t nValueReferences,
            fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
UNSUPPORTED(fmi3GetIntervalFraction, const fmi3ValueReference valueReferences[], size_t nValueReferences,
            fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[])
UNSUPPORTED(fmi3GetShiftDecimal, const fmi3ValueReference valueReferences[], size_t nValueReferences,
            fmi3Float64 shifts[])
UNSUPPORTED(fmi3GetShiftFraction, const fmi3ValueReference valueReferences[], size_t nValueReferences,
            fmi3UInt64 counters[], fmi3UInt64 resolutions[])
UNSUPPORTED(fmi3SetIntervalDecimal, const fmi3ValueReference valueReferences[], size_t nValueReferences,
            const fmi3Float64 intervals[])
UNSUPPORTED(fmi3SetIntervalFraction, const fmi3ValueReference valueReferences[], size_t nValueReferences,
            const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
UNSUPPORTED(fmi3SetShiftDecimal, const fmi3ValueReference valueReferences[], size_t nValueReferences,
            const fmi3Float64 shifts[])
UNSUPPORTED(fmi3SetShiftFraction, const fmi3ValueReference valueReferences[], size_t nValueReferences,
            const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
UNSUPPORTED0(fmi3EvaluateDiscreteStates)
UNSUPPORTED(fmi3UpdateDiscreteStates, fmi3Boolean *discreteStatesNeedUpdate, fmi3Boolean *terminateSimulation,
            fmi3Boolean *nominalsOfContinuousStatesChanged, fmi3Boolean *valuesOfContinuousStatesChanged,
            fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime)
UNSUPPORTED0(fmi3EnterEventMode)
UNSUPPORTED0(fmi3EnterContinuousTimeMode)
UNSUPPORTED(fmi3CompletedIntegratorStep, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
            fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
UNSUPPORTED(fmi3SetTime, fmi3Float64 time)
UNSUPPORTED(fmi3SetContinuousStates, const fmi3Float64 continuousStates[], size_t nContinuousStates)
UNSUPPORTED(fmi3GetContinuousStateDerivatives, fmi3Float64 derivatives[], size_t nContinuousStates)
UNSUPPORTED(fmi3GetEventIndicators, fmi3Float64 eventIndicators[], size_t nEventIndicators)
UNSUPPORTED(fmi3GetContinuousStates, fmi3Float64 continuousStates[], size_t nContinuousStates)
UNSUPPORTED(fmi3GetNominalsOfContinuousStates, fmi3Float64 nominals[], size_t nContinuousStates)
UNSUPPORTED(fmi3GetNumberOfEventIndicators, size_t *nEventIndicators)
UNSUPPORTED(fmi3GetNumberOfContinuousStates, size_t *nContinuousStates)
UNSUPPORTED(fmi3GetOutputDerivatives, const fmi3ValueReference valueReferences[], size_t nValueReferences,
            const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues)
UNSUPPORTED(fmi3ActivateModelPartition, fmi3ValueReference clockReference, fmi3Float64 activationTime)
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif
