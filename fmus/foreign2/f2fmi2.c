/* FMI 2.0 co-simulation API of a foreign2 plant over f2core (Foreign2ZStage). Written for
 * drillcosim issue 20; shares nothing with fmus/common or fmus/foreign. */
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "f2core.h"

#define INST ((F2Inst *)c)

static void emit2(F2Inst *c, int is_error, const char *msg) {
    const fmi2CallbackFunctions *cb = (const fmi2CallbackFunctions *)c->cb;
    if (cb && cb->logger)
        cb->logger(cb->componentEnvironment, c->name, is_error ? fmi2Error : fmi2OK,
                   is_error ? "logStatusError" : "logAll", "%s", msg);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    INST->logging = on ? 1 : 0;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging) {
    if (type != fmi2CoSimulation || !guid || strcmp(guid, f2_token) != 0) {
        if (cb && cb->logger)
            cb->logger(cb->componentEnvironment, name, fmi2Error, "logStatusError",
                       "fmi2Instantiate: %s", type != fmi2CoSimulation ? "only co-simulation is supported"
                                                                       : "the GUID does not match this binary");
        return NULL;
    }
    return f2_new(name, emit2, cb, NULL, logging);
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tol_on, fmi2Real tol, fmi2Real t0,
                               fmi2Boolean stop_on, fmi2Real t_stop) {
    INST->s.t = t0;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    INST->phase = F2_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    return f2_enter_run(INST, "fmi2ExitInitializationMode") ? fmi2OK : fmi2Error;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    INST->phase = F2_DONE;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    f2_reset(INST);
    return fmi2OK;
}

/* one getter/setter body for Real, Integer and Boolean (all held as doubles) */
#define GETTER(Fn, T)                                                                        \
    fmi2Status Fn(fmi2Component c, const fmi2ValueReference vr[], size_t n, T value[]) {     \
        for (size_t k = 0; k < n; k++) {                                                     \
            double x;                                                                        \
            if (!f2_get(INST, #Fn, vr[k], &x)) return fmi2Error;                             \
            value[k] = (T)x;                                                                 \
        }                                                                                    \
        return fmi2OK;                                                                       \
    }
#define SETTER(Fn, T)                                                                        \
    fmi2Status Fn(fmi2Component c, const fmi2ValueReference vr[], size_t n, const T value[]) { \
        for (size_t k = 0; k < n; k++)                                                       \
            if (!f2_set(INST, #Fn, vr[k], (double)value[k])) return fmi2Error;               \
        return fmi2OK;                                                                       \
    }
GETTER(fmi2GetReal, fmi2Real)
GETTER(fmi2GetInteger, fmi2Integer)
GETTER(fmi2GetBoolean, fmi2Boolean)
SETTER(fmi2SetReal, fmi2Real)
SETTER(fmi2SetInteger, fmi2Integer)
SETTER(fmi2SetBoolean, fmi2Boolean)

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String value[]) {
    f2_log(INST, 1, "fmi2GetString: the model has no String variables");
    return n ? fmi2Error : fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String value[]) {
    f2_log(INST, 1, "fmi2SetString: the model has no String variables");
    return n ? fmi2Error : fmi2OK;
}

/* FMU states: a copy of the plain-data F2State */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    return f2_state_get(INST, state) ? fmi2OK : fmi2Error;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    return f2_state_set(INST, state) ? fmi2OK : fmi2Error;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    f2_state_free(state);
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    *size = sizeof(F2State);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size) {
    return f2_state_pack(state, bytes, size) ? fmi2OK : fmi2Error;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *state) {
    if (size != sizeof(F2State)) {
        f2_log(INST, 1, "fmi2DeSerializeFMUstate: %zu bytes, expected %zu", size, sizeof(F2State));
        return fmi2Error;
    }
    return f2_state_unpack(bytes, state) ? fmi2OK : fmi2Error;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[],
                                        fmi2Real dz[]) {
    f2_log(INST, 1, "fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative=false)");
    return fmi2Error;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    f2_log(INST, 1, "fmi2SetRealInputDerivatives: not supported (canInterpolateInputs=false)");
    return fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[]) {
    f2_log(INST, 1, "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder=0)");
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real H, fmi2Boolean no_prior) {
    return f2_do_step(INST, "fmi2DoStep", t, H) ? fmi2OK : fmi2Error;
}

fmi2Status fmi2CancelStep(fmi2Component c) { return fmi2Error; }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    *value = fmi2OK;
    return fmi2OK;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    if (s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = INST->s.t;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    if (s != fmi2Terminated) return fmi2Discard;
    *value = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    return fmi2Discard;
}
