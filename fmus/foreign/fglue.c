/* Hand-written FMI 3.0 co-simulation glue shared by the foreign plants.
 *
 * Written for the foreign-plant fixture (issue 10): a different route from the project's
 * generated frames in fmus/common/. One instance = FgInst; values by value reference in
 * FgData.v; the model (fglue.h hooks) integrates. Only Float64 and Int32 variables exist;
 * every other FMI 3.0 function is exported and answers an empty request with fmi3OK and
 * anything else with fmi3Error and a logged message. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "fglue.h"

typedef enum { M_INSTANTIATED, M_INIT, M_STEP, M_TERMINATED } Mode;

struct FgInst {
    FgData data;
    Mode mode;
    char name[128];
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
    short index[FG_MAXVR];   /* value reference -> FG_VARS index, -1 if none */
};

FgData *fg_data(FgInst *c) { return &c->data; }

static void vlog(FgInst *c, fmi3Status st, const char *cat, const char *fmt, va_list ap) {
    char buf[512];
    if (!c || !c->log) return;
    vsnprintf(buf, sizeof buf, fmt, ap);
    c->log(c->env, st, cat, buf);
}

void fg_log_error(FgInst *c, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vlog(c, fmi3Error, "logStatusError", fmt, ap);
    va_end(ap);
}

/* ------------------------------------------------------------------ noise: PCG32 + polar */

static uint32_t pcg32(FgData *d) {
    uint64_t old = d->rng_state;
    d->rng_state = old * 6364136223846793005ULL + d->rng_inc;
    uint32_t xs = (uint32_t)(((old >> 18u) ^ old) >> 27u);
    uint32_t rot = (uint32_t)(old >> 59u);
    return (xs >> rot) | (xs << ((-rot) & 31));
}

static void seed_rng(FgData *d, uint64_t seed) {
    d->rng_state = 0u;
    d->rng_inc = (seed << 1u) | 1u;
    pcg32(d);
    d->rng_state += 0x9E3779B97F4A7C15ULL ^ seed;
    pcg32(d);
    d->have_spare = 0;
}

double fg_gauss(FgData *d) {
    if (d->have_spare) {
        d->have_spare = 0;
        return d->spare;
    }
    double u, w, x;
    do {
        u = 2.0 * (pcg32(d) + 0.5) / 4294967296.0 - 1.0;
        x = 2.0 * (pcg32(d) + 0.5) / 4294967296.0 - 1.0;
        w = u * u + x * x;
    } while (w >= 1.0 || w == 0.0);
    w = sqrt(-2.0 * log(w) / w);
    d->spare = x * w;
    d->have_spare = 1;
    return u * w;
}

/* ------------------------------------------------------------------ helpers */

static void set_defaults(FgInst *c) {
    memset(&c->data, 0, sizeof c->data);
    for (int k = 0; k < FG_NVARS; k++) c->data.v[FG_VARS[k].vr] = FG_VARS[k].start;
    c->data.dirty = 1;
}

static const FgVar *lookup(FgInst *c, fmi3ValueReference vr, const char *fn) {
    if (vr >= FG_MAXVR || c->index[vr] < 0) {
        fg_log_error(c, "%s: unknown value reference %u", fn, (unsigned)vr);
        return NULL;
    }
    return &FG_VARS[c->index[vr]];
}

static int in_range(const FgVar *var, double x) {
    return var->min > var->max || (x >= var->min && x <= var->max);
}

static void range_message(FgInst *c, const char *fn, const FgVar *var, double x) {
    fg_log_error(c, "%s: %s = %g %s is out of range: expected %g .. %g %s", fn, var->name, x,
                 var->unit, var->min, var->max, var->unit);
}

/* may `var` be set now? (FMI 3.0 rules for fixed/tunable parameters and inputs) */
static int settable(FgInst *c, const FgVar *var, const char *fn) {
    switch (var->caus) {
    case FG_OUTPUT:
        fg_log_error(c, "%s: %s is an output and cannot be set", fn, var->name);
        return 0;
    case FG_PARAM:
        if (c->mode != M_INSTANTIATED && c->mode != M_INIT) {
            fg_log_error(c, "%s: %s is a fixed parameter: set it before fmi3ExitInitializationMode",
                         fn, var->name);
            return 0;
        }
        return 1;
    default:
        if (c->mode == M_TERMINATED) {
            fg_log_error(c, "%s: instance is terminated", fn);
            return 0;
        }
        return 1;
    }
}

static fmi3Status set_values(FgInst *c, const fmi3ValueReference vr[], size_t n, const double *x,
                             FgType type, const char *fn) {
    /* validate all first: a refused call changes nothing */
    for (size_t k = 0; k < n; k++) {
        const FgVar *var = lookup(c, vr[k], fn);
        if (!var) return fmi3Error;
        if (var->type != type) {
            fg_log_error(c, "%s: %s is %s", fn, var->name, var->type == FG_F64 ? "Float64" : "Int32");
            return fmi3Error;
        }
        if (!settable(c, var, fn)) return fmi3Error;
        if (!isfinite(x[k])) {
            fg_log_error(c, "%s: %s = %g is not a finite number", fn, var->name, x[k]);
            return fmi3Error;
        }
        if (c->mode == M_STEP && var->caus == FG_TUNABLE && !in_range(var, x[k])) {
            range_message(c, fn, var, x[k]);
            return fmi3Error;
        }
    }
    for (size_t k = 0; k < n; k++) {
        c->data.v[vr[k]] = x[k];
        if (FG_VARS[c->index[vr[k]]].caus != FG_INPUT) c->data.dirty = 1;
    }
    return fmi3OK;
}

static fmi3Status get_values(FgInst *c, const fmi3ValueReference vr[], size_t n, double *x,
                             FgType type, const char *fn) {
    for (size_t k = 0; k < n; k++) {
        if (vr[k] == 0 && type == FG_F64) {
            x[k] = c->data.time;
            continue;
        }
        const FgVar *var = lookup(c, vr[k], fn);
        if (!var) return fmi3Error;
        if (var->type != type) {
            fg_log_error(c, "%s: %s is %s", fn, var->name, var->type == FG_F64 ? "Float64" : "Int32");
            return fmi3Error;
        }
        x[k] = c->data.v[vr[k]];
    }
    return fmi3OK;
}

/* ------------------------------------------------------------------ FMI 3.0 API */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    return fmi3OK;   /* errors are always logged; there is nothing else to log */
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible,
                                         fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
                                         fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    FgInst tmp = {.env = instanceEnvironment, .log = logMessage};
    if (!instantiationToken || strcmp(instantiationToken, FG_TOKEN) != 0) {
        fg_log_error(&tmp, "fmi3InstantiateCoSimulation: instantiationToken %s does not match %s",
                     instantiationToken ? instantiationToken : "(null)", FG_TOKEN);
        return NULL;
    }
    if (eventModeUsed || nRequiredIntermediateVariables > 0) {
        fg_log_error(&tmp, "fmi3InstantiateCoSimulation: event mode and intermediate variables "
                           "are not supported");
        return NULL;
    }
    FgInst *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    c->env = instanceEnvironment;
    c->log = logMessage;
    snprintf(c->name, sizeof c->name, "%s", instanceName ? instanceName : "");
    for (int k = 0; k < FG_MAXVR; k++) c->index[k] = -1;
    for (int k = 0; k < FG_NVARS; k++) c->index[FG_VARS[k].vr] = (short)k;
    set_defaults(c);
    c->mode = M_INSTANTIATED;
    return c;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    FgInst tmp = {.env = instanceEnvironment, .log = logMessage};
    fg_log_error(&tmp, "fmi3InstantiateModelExchange: this FMU is co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible,
                                               fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage,
                                               fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    FgInst tmp = {.env = instanceEnvironment, .log = logMessage};
    fg_log_error(&tmp, "fmi3InstantiateScheduledExecution: this FMU is co-simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    FgInst *c = instance;
    if (c->mode != M_INSTANTIATED) {
        fg_log_error(c, "fmi3EnterInitializationMode: only allowed after instantiation or reset");
        return fmi3Error;
    }
    c->data.time = startTime;
    c->mode = M_INIT;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    FgInst *c = instance;
    const char *fn = "fmi3ExitInitializationMode";
    if (c->mode != M_INIT) {
        fg_log_error(c, "%s: not in initialization mode", fn);
        return fmi3Error;
    }
    for (int k = 0; k < FG_NVARS; k++) {
        const FgVar *var = &FG_VARS[k];
        double x = c->data.v[var->vr];
        if ((var->caus == FG_PARAM || var->caus == FG_TUNABLE) && !in_range(var, x)) {
            range_message(c, fn, var, x);
            return fmi3Error;
        }
    }
    if (!fg_model_check(c, fn)) return fmi3Error;
    seed_rng(&c->data, (uint64_t)(int64_t)c->data.v[FG_SEED_VR]);
    c->mode = M_STEP;
    fg_model_init(&c->data);
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    fg_log_error(instance, "fmi3EnterEventMode: event mode is not supported");
    return fmi3Error;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    ((FgInst *)instance)->mode = M_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    FgInst *c = instance;
    set_defaults(c);
    c->mode = M_INSTANTIATED;
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    return get_values(instance, valueReferences, nValueReferences, values, FG_F64, "fmi3GetFloat64");
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[], size_t nValues) {
    return set_values(instance, valueReferences, nValueReferences, values, FG_F64, "fmi3SetFloat64");
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Int32 values[], size_t nValues) {
    double x[FG_MAXVR];
    if (nValueReferences > FG_MAXVR) return fmi3Error;
    fmi3Status st = get_values(instance, valueReferences, nValueReferences, x, FG_I32, "fmi3GetInt32");
    for (size_t k = 0; st == fmi3OK && k < nValueReferences; k++) values[k] = (fmi3Int32)x[k];
    return st;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Int32 values[], size_t nValues) {
    double x[FG_MAXVR];
    if (nValueReferences > FG_MAXVR) return fmi3Error;
    for (size_t k = 0; k < nValueReferences; k++) x[k] = values[k];
    return set_values(instance, valueReferences, nValueReferences, x, FG_I32, "fmi3SetInt32");
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance) { return fmi3OK; }

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    FgInst *c = instance;
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = c->data.time;
    if (c->mode != M_STEP) {
        fg_log_error(c, "fmi3DoStep: not in step mode (call fmi3ExitInitializationMode first)");
        return fmi3Error;
    }
    if (!(communicationStepSize > 0.0) || !isfinite(communicationStepSize)) {
        fg_log_error(c, "fmi3DoStep: communication step size %g is invalid: expected > 0",
                     communicationStepSize);
        return fmi3Error;
    }
    fg_model_step(&c->data, communicationStepSize);
    c->data.time = currentCommunicationPoint + communicationStepSize;
    for (int k = 0; k < FG_NVARS; k++) {
        if (!isfinite(c->data.v[FG_VARS[k].vr])) {
            fg_log_error(c, "fmi3DoStep: %s became %g at t = %g s (integration diverged)",
                         FG_VARS[k].name, c->data.v[FG_VARS[k].vr], c->data.time);
            c->mode = M_TERMINATED;
            return fmi3Error;
        }
    }
    *lastSuccessfulTime = c->data.time;
    return fmi3OK;
}

/* FMU states: a copy of the plain data block */
fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    FgData *s = *FMUState ? (FgData *)*FMUState : malloc(sizeof(FgData));
    if (!s) return fmi3Error;
    *s = ((FgInst *)instance)->data;
    *FMUState = s;
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    if (!FMUState) return fmi3Error;
    ((FgInst *)instance)->data = *(FgData *)FMUState;
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    free(*FMUState);
    *FMUState = NULL;
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    *size = sizeof(FgData);
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                 fmi3Byte serializedState[], size_t size) {
    if (size != sizeof(FgData)) return fmi3Error;
    memcpy(serializedState, FMUState, size);
    return fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUState) {
    if (size != sizeof(FgData)) {
        fg_log_error(instance, "fmi3DeserializeFMUState: %zu bytes, expected %zu", size, sizeof(FgData));
        return fmi3Error;
    }
    FgData *s = *FMUState ? (FgData *)*FMUState : malloc(sizeof(FgData));
    if (!s) return fmi3Error;
    memcpy(s, serializedState, size);
    *FMUState = s;
    return fmi3OK;
}

/* ------------------------------------------------------------------ unsupported types and modes */

#define FG_NO_TYPE(fname, ctype, constness)                                                        \
    fmi3Status fname(fmi3Instance instance, const fmi3ValueReference valueReferences[],           \
                     size_t nValueReferences, constness ctype values[], size_t nValues) {         \
        if (nValueReferences == 0) return fmi3OK;                                                 \
        fg_log_error(instance, #fname ": value reference %u: this FMU has only Float64 and Int32 " \
                     "variables", (unsigned)valueReferences[0]);                                  \
        return fmi3Error;                                                                         \
    }

FG_NO_TYPE(fmi3GetFloat32, fmi3Float32, )
FG_NO_TYPE(fmi3GetInt8, fmi3Int8, )
FG_NO_TYPE(fmi3GetUInt8, fmi3UInt8, )
FG_NO_TYPE(fmi3GetInt16, fmi3Int16, )
FG_NO_TYPE(fmi3GetUInt16, fmi3UInt16, )
FG_NO_TYPE(fmi3GetUInt32, fmi3UInt32, )
FG_NO_TYPE(fmi3GetInt64, fmi3Int64, )
FG_NO_TYPE(fmi3GetUInt64, fmi3UInt64, )
FG_NO_TYPE(fmi3GetBoolean, fmi3Boolean, )
FG_NO_TYPE(fmi3GetString, fmi3String, )
FG_NO_TYPE(fmi3SetFloat32, fmi3Float32, const)
FG_NO_TYPE(fmi3SetInt8, fmi3Int8, const)
FG_NO_TYPE(fmi3SetUInt8, fmi3UInt8, const)
FG_NO_TYPE(fmi3SetInt16, fmi3Int16, const)
FG_NO_TYPE(fmi3SetUInt16, fmi3UInt16, const)
FG_NO_TYPE(fmi3SetUInt32, fmi3UInt32, const)
FG_NO_TYPE(fmi3SetInt64, fmi3Int64, const)
FG_NO_TYPE(fmi3SetUInt64, fmi3UInt64, const)
FG_NO_TYPE(fmi3SetBoolean, fmi3Boolean, const)
FG_NO_TYPE(fmi3SetString, fmi3String, const)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, size_t valueSizes[], fmi3Binary values[],
                         size_t nValues) {
    return nValueReferences == 0 ? fmi3OK : fmi3Error;
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues) {
    return nValueReferences == 0 ? fmi3OK : fmi3Error;
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Clock values[]) {
    return nValueReferences == 0 ? fmi3OK : fmi3Error;
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Clock values[]) {
    return nValueReferences == 0 ? fmi3OK : fmi3Error;
}

#define FG_UNSUPPORTED(what) \
    do { fg_log_error(instance, "%s is not supported by this FMU", what); return fmi3Error; } while (0)

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    FG_UNSUPPORTED("fmi3GetNumberOfVariableDependencies");
}
fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[], size_t nDependencies) {
    FG_UNSUPPORTED("fmi3GetVariableDependencies");
}
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                        size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns,
                                        const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[],
                                        size_t nSensitivity) {
    FG_UNSUPPORTED("fmi3GetDirectionalDerivative");
}
fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                    size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns,
                                    const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[],
                                    size_t nSensitivity) {
    FG_UNSUPPORTED("fmi3GetAdjointDerivative");
}
fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) { FG_UNSUPPORTED("fmi3EnterConfigurationMode"); }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) { FG_UNSUPPORTED("fmi3ExitConfigurationMode"); }
fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[]) {
    FG_UNSUPPORTED("fmi3GetIntervalDecimal");
}
fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    FG_UNSUPPORTED("fmi3GetIntervalFraction");
}
fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[]) {
    FG_UNSUPPORTED("fmi3GetShiftDecimal");
}
fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    FG_UNSUPPORTED("fmi3GetShiftFraction");
}
fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[]) {
    FG_UNSUPPORTED("fmi3SetIntervalDecimal");
}
fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[]) {
    FG_UNSUPPORTED("fmi3SetIntervalFraction");
}
fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[]) {
    FG_UNSUPPORTED("fmi3SetShiftDecimal");
}
fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[],
                                const fmi3UInt64 resolutions[]) {
    FG_UNSUPPORTED("fmi3SetShiftFraction");
}
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) { FG_UNSUPPORTED("fmi3EvaluateDiscreteStates"); }
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation,
                                    fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged,
                                    fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime) {
    FG_UNSUPPORTED("fmi3UpdateDiscreteStates");
}
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) { FG_UNSUPPORTED("fmi3EnterContinuousTimeMode"); }
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    FG_UNSUPPORTED("fmi3CompletedIntegratorStep");
}
fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) { FG_UNSUPPORTED("fmi3SetTime"); }
fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    FG_UNSUPPORTED("fmi3SetContinuousStates");
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    FG_UNSUPPORTED("fmi3GetContinuousStateDerivatives");
}
fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators) {
    FG_UNSUPPORTED("fmi3GetEventIndicators");
}
fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    FG_UNSUPPORTED("fmi3GetContinuousStates");
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    FG_UNSUPPORTED("fmi3GetNominalsOfContinuousStates");
}
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    FG_UNSUPPORTED("fmi3GetNumberOfEventIndicators");
}
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    FG_UNSUPPORTED("fmi3GetNumberOfContinuousStates");
}
fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues) {
    FG_UNSUPPORTED("fmi3GetOutputDerivatives");
}
fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    FG_UNSUPPORTED("fmi3ActivateModelPartition");
}
