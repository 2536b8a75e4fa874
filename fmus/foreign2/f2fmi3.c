/* FMI 3.0 co-simulation API of a foreign2 plant over f2core (Foreign2BallScrew). Written for
 * drillcosim issue 20; shares nothing with fmus/common or fmus/foreign. Float64 and Int32
 * variables only; every other type, Model Exchange and Scheduled Execution are refused. */
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "f2core.h"

#define INST ((F2Inst *)c)

static void emit3(F2Inst *c, int is_error, const char *msg) {
    fmi3LogMessageCallback log = (fmi3LogMessageCallback)c->cb;
    if (log) log(c->env, is_error ? fmi3Error : fmi3OK, is_error ? "logStatusError" : "logAll", msg);
}

static fmi3Status refuse(fmi3Instance c, const char *fn) {
    if (c) f2_log(INST, 1, "%s: not supported by this FMU (co-simulation with Float64/Int32 variables)", fn);
    return fmi3Error;
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n, const fmi3String cats[]) {
    INST->logging = on ? 1 : 0;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources,
                                         fmi3Boolean visible, fmi3Boolean logging, fmi3Boolean event_mode,
                                         fmi3Boolean early_return, const fmi3ValueReference req[], size_t nreq,
                                         fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
                                         fmi3IntermediateUpdateCallback upd) {
    if (!token || strcmp(token, f2_token) != 0) {
        if (log) log(env, fmi3Error, "logStatusError",
                     "fmi3InstantiateCoSimulation: the instantiation token does not match this binary");
        return NULL;
    }
    if (event_mode) {
        if (log) log(env, fmi3Error, "logStatusError",
                     "fmi3InstantiateCoSimulation: event mode is not supported (hasEventMode=false)");
        return NULL;
    }
    return f2_new(name, emit3, (const void *)log, env, logging);
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resources,
                                          fmi3Boolean visible, fmi3Boolean logging,
                                          fmi3InstanceEnvironment env, fmi3LogMessageCallback log) {
    if (log) log(env, fmi3Error, "logStatusError", "fmi3InstantiateModelExchange: co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String name, fmi3String token, fmi3String resources,
                                               fmi3Boolean visible, fmi3Boolean logging,
                                               fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
                                               fmi3ClockUpdateCallback clk, fmi3LockPreemptionCallback lock,
                                               fmi3UnlockPreemptionCallback unlock) {
    if (log) log(env, fmi3Error, "logStatusError", "fmi3InstantiateScheduledExecution: co-simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance c) { free(c); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean tol_on, fmi3Float64 tol, fmi3Float64 t0,
                                       fmi3Boolean stop_on, fmi3Float64 t_stop) {
    INST->s.t = t0;
    INST->phase = F2_INIT;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    return f2_enter_run(INST, "fmi3ExitInitializationMode") ? fmi3OK : fmi3Error;
}

fmi3Status fmi3EnterEventMode(fmi3Instance c) { return refuse(c, "fmi3EnterEventMode"); }
fmi3Status fmi3EnterStepMode(fmi3Instance c) { return fmi3OK; }

fmi3Status fmi3Terminate(fmi3Instance c) {
    INST->phase = F2_DONE;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance c) {
    f2_reset(INST);
    return fmi3OK;
}

/* scalar variables only: nValues must equal nValueReferences */
#define GET3(Fn, T)                                                                              \
    fmi3Status Fn(fmi3Instance c, const fmi3ValueReference vr[], size_t n, T values[], size_t nv) { \
        if (nv != n) return refuse(c, #Fn " with arrays");                                       \
        for (size_t k = 0; k < n; k++) {                                                         \
            double x;                                                                            \
            if (!f2_get(INST, #Fn, vr[k], &x)) return fmi3Error;                                 \
            values[k] = (T)x;                                                                    \
        }                                                                                        \
        return fmi3OK;                                                                           \
    }
#define SET3(Fn, T)                                                                              \
    fmi3Status Fn(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const T values[], size_t nv) { \
        if (nv != n) return refuse(c, #Fn " with arrays");                                       \
        for (size_t k = 0; k < n; k++)                                                           \
            if (!f2_set(INST, #Fn, vr[k], (double)values[k])) return fmi3Error;                  \
        return fmi3OK;                                                                           \
    }
#define NO_GET3(Fn, T)                                                                           \
    fmi3Status Fn(fmi3Instance c, const fmi3ValueReference vr[], size_t n, T values[], size_t nv) { \
        return n ? refuse(c, #Fn) : fmi3OK;                                                      \
    }
#define NO_SET3(Fn, T)                                                                           \
    fmi3Status Fn(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const T values[], size_t nv) { \
        return n ? refuse(c, #Fn) : fmi3OK;                                                      \
    }
GET3(fmi3GetFloat64, fmi3Float64)
GET3(fmi3GetInt32, fmi3Int32)
SET3(fmi3SetFloat64, fmi3Float64)
SET3(fmi3SetInt32, fmi3Int32)
NO_GET3(fmi3GetFloat32, fmi3Float32)
NO_GET3(fmi3GetInt8, fmi3Int8)
NO_GET3(fmi3GetUInt8, fmi3UInt8)
NO_GET3(fmi3GetInt16, fmi3Int16)
NO_GET3(fmi3GetUInt16, fmi3UInt16)
NO_GET3(fmi3GetUInt32, fmi3UInt32)
NO_GET3(fmi3GetInt64, fmi3Int64)
NO_GET3(fmi3GetUInt64, fmi3UInt64)
NO_GET3(fmi3GetBoolean, fmi3Boolean)
NO_GET3(fmi3GetString, fmi3String)
NO_SET3(fmi3SetFloat32, fmi3Float32)
NO_SET3(fmi3SetInt8, fmi3Int8)
NO_SET3(fmi3SetUInt8, fmi3UInt8)
NO_SET3(fmi3SetInt16, fmi3Int16)
NO_SET3(fmi3SetUInt16, fmi3UInt16)
NO_SET3(fmi3SetUInt32, fmi3UInt32)
NO_SET3(fmi3SetInt64, fmi3Int64)
NO_SET3(fmi3SetUInt64, fmi3UInt64)
NO_SET3(fmi3SetBoolean, fmi3Boolean)
NO_SET3(fmi3SetString, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t n, size_t sizes[],
                         fmi3Binary values[], size_t nv) {
    return n ? refuse(c, "fmi3GetBinary") : fmi3OK;
}

fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const size_t sizes[],
                         const fmi3Binary values[], size_t nv) {
    return n ? refuse(c, "fmi3SetBinary") : fmi3OK;
}

fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Clock values[]) {
    return n ? refuse(c, "fmi3GetClock") : fmi3OK;
}

fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Clock values[]) {
    return n ? refuse(c, "fmi3SetClock") : fmi3OK;
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance c, fmi3ValueReference vr, size_t *n) {
    return refuse(c, "fmi3GetNumberOfVariableDependencies");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance c, fmi3ValueReference dep, size_t ed[],
                                       fmi3ValueReference ind[], size_t ei[], fmi3DependencyKind kinds[],
                                       size_t n) {
    return refuse(c, "fmi3GetVariableDependencies");
}

/* FMU states: a copy of the plain-data F2State */
fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *state) {
    return f2_state_get(INST, state) ? fmi3OK : fmi3Error;
}

fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState state) {
    return f2_state_set(INST, state) ? fmi3OK : refuse(c, "fmi3SetFMUState with a NULL state");
}

fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *state) {
    f2_state_free(state);
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState state, size_t *size) {
    *size = sizeof(F2State);
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState state, fmi3Byte bytes[], size_t size) {
    return f2_state_pack(state, bytes, size) ? fmi3OK : refuse(c, "fmi3SerializeFMUState into a short buffer");
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte bytes[], size_t size, fmi3FMUState *state) {
    if (size != sizeof(F2State)) return refuse(c, "fmi3DeserializeFMUState of a foreign size");
    return f2_state_unpack(bytes, state) ? fmi3OK : fmi3Error;
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance c, const fmi3ValueReference u[], size_t nu,
                                        const fmi3ValueReference k[], size_t nk, const fmi3Float64 seed[],
                                        size_t ns, fmi3Float64 sens[], size_t nsens) {
    return refuse(c, "fmi3GetDirectionalDerivative");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance c, const fmi3ValueReference u[], size_t nu,
                                    const fmi3ValueReference k[], size_t nk, const fmi3Float64 seed[],
                                    size_t ns, fmi3Float64 sens[], size_t nsens) {
    return refuse(c, "fmi3GetAdjointDerivative");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) { return refuse(c, "fmi3EnterConfigurationMode"); }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) { return refuse(c, "fmi3ExitConfigurationMode"); }

fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 iv[],
                                  fmi3IntervalQualifier q[]) {
    return refuse(c, "fmi3GetIntervalDecimal");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3UInt64 cnt[],
                                   fmi3UInt64 res[], fmi3IntervalQualifier q[]) {
    return refuse(c, "fmi3GetIntervalFraction");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 sh[]) {
    return refuse(c, "fmi3GetShiftDecimal");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3UInt64 cnt[],
                                fmi3UInt64 res[]) {
    return refuse(c, "fmi3GetShiftFraction");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                                  const fmi3Float64 iv[]) {
    return refuse(c, "fmi3SetIntervalDecimal");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                                   const fmi3UInt64 cnt[], const fmi3UInt64 res[]) {
    return refuse(c, "fmi3SetIntervalFraction");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 sh[]) {
    return refuse(c, "fmi3SetShiftDecimal");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                                const fmi3UInt64 cnt[], const fmi3UInt64 res[]) {
    return refuse(c, "fmi3SetShiftFraction");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) { return refuse(c, "fmi3EvaluateDiscreteStates"); }

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *need, fmi3Boolean *term, fmi3Boolean *nom,
                                    fmi3Boolean *vals, fmi3Boolean *next_def, fmi3Float64 *next) {
    return refuse(c, "fmi3UpdateDiscreteStates");
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) { return refuse(c, "fmi3EnterContinuousTimeMode"); }

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean no_prior, fmi3Boolean *event,
                                       fmi3Boolean *term) {
    return refuse(c, "fmi3CompletedIntegratorStep");
}

fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 t) { return refuse(c, "fmi3SetTime"); }

fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 x[], size_t n) {
    return refuse(c, "fmi3SetContinuousStates");
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 dx[], size_t n) {
    return refuse(c, "fmi3GetContinuousStateDerivatives");
}

fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 ind[], size_t n) {
    return refuse(c, "fmi3GetEventIndicators");
}

fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t n) {
    return refuse(c, "fmi3GetContinuousStates");
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 nom[], size_t n) {
    return refuse(c, "fmi3GetNominalsOfContinuousStates");
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *n) {
    return refuse(c, "fmi3GetNumberOfEventIndicators");
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *n) {
    return refuse(c, "fmi3GetNumberOfContinuousStates");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nv) {
    return refuse(c, "fmi3GetOutputDerivatives");
}

fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 H, fmi3Boolean no_prior, fmi3Boolean *event,
                      fmi3Boolean *term, fmi3Boolean *early, fmi3Float64 *last) {
    int ok = f2_do_step(INST, "fmi3DoStep", t, H);
    if (event) *event = fmi3False;
    if (term) *term = fmi3False;
    if (early) *early = fmi3False;
    if (last) *last = INST->s.t;
    return ok ? fmi3OK : fmi3Error;
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference clk, fmi3Float64 t) {
    return refuse(c, "fmi3ActivateModelPartition");
}
