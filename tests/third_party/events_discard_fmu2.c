/* Test FMU (FMI 2.0, Model Exchange + Co-Simulation in one binary) for drillcosim
 * issue #7. Built by tests/third_party/c_test_fmu.py with the system gcc against
 * fmpy's FMI headers; not a plant.
 *
 * Model Exchange: a bouncing ball with an extra state
 *     der(h) = v,  der(v) = -g_now + u,  der(x) = u
 *   state event : event indicator z0 = h; when h <= 0 with v < 0: v := -e*v, n_bounces += 1
 *   time event  : at t = t_switch (if >= 0) g_now switches from g1 to g2
 *   step event  : if step_event_every = N > 0, every Nth completedIntegratorStep asks
 *                 for an event, which counts n_step_events += 1
 * Co-Simulation: only x evolves, exactly: x(t+h) = x(t) + u*h;
 *   fmi2DoStep returns fmi2Discard (state unchanged) when h > discard_above;
 *   n_steps_done counts accepted steps. Both interfaces support
 *   fmi2GetFMUstate / fmi2SetFMUstate / fmi2FreeFMUstate.
 */
#include <stdlib.h>
#include <string.h>
#include <stdio.h>
#include "fmi2Functions.h"

enum { VR_H, VR_DER_H, VR_V, VR_DER_V, VR_G1, VR_G2, VR_T_SWITCH, VR_E, VR_U, VR_G_NOW,
       VR_N_BOUNCES, VR_STEP_EVERY, VR_N_STEP_EVENTS, VR_DISCARD_ABOVE, VR_X, VR_DER_X,
       VR_N_STEPS_DONE, NVR };

typedef struct {
    double r[NVR];
    double time;
    int is_cs;
    long n_completed;
    int step_event_pending;
    int time_event_done;
    fmi2CallbackFunctions cb;
    char name[128];
} Inst;

static void logmsg(Inst *c, fmi2Status st, const char *cat, const char *msg) {
    if (c->cb.logger) c->cb.logger(c->cb.componentEnvironment, c->name, st, cat, "%s", msg);
}

static void derivs(Inst *c) {
    c->r[VR_DER_H] = c->r[VR_V];
    c->r[VR_DER_V] = -c->r[VR_G_NOW] + c->r[VR_U];
    c->r[VR_DER_X] = c->r[VR_U];
}

const char* fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char* fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) { return fmi2OK; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions* cb, fmi2Boolean visible, fmi2Boolean logOn) {
    Inst *c = (Inst*)calloc(1, sizeof(Inst));
    if (!c) return NULL;
    c->cb = *cb;
    strncpy(c->name, name ? name : "", sizeof(c->name) - 1);
    c->is_cs = (type == fmi2CoSimulation);
    c->r[VR_H] = 1.0; c->r[VR_V] = 0.0; c->r[VR_G1] = 9.81; c->r[VR_G2] = 3.0;
    c->r[VR_T_SWITCH] = -1.0; c->r[VR_E] = 0.8; c->r[VR_U] = 0.0;
    c->r[VR_STEP_EVERY] = 0.0; c->r[VR_DISCARD_ABOVE] = 1.0; c->r[VR_X] = 0.0;
    return c;
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean td, fmi2Real tol, fmi2Real t0, fmi2Boolean sd, fmi2Real t1) {
    ((Inst*)c)->time = t0; return fmi2OK;
}
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Inst *s = (Inst*)c;
    s->r[VR_G_NOW] = s->r[VR_G1];
    derivs(s);
    return fmi2OK;
}
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { return fmi2Error; }

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Inst *s = (Inst*)c; derivs(s);
    for (size_t i = 0; i < n; i++) { if (vr[i] >= NVR) return fmi2Error; v[i] = s->r[vr[i]]; }
    return fmi2OK;
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Inst *s = (Inst*)c;
    for (size_t i = 0; i < n; i++) { if (vr[i] >= NVR) return fmi2Error; s->r[vr[i]] = v[i]; }
    return fmi2OK;
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) { return n ? fmi2Error : fmi2OK; }

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate* st) {
    Inst *copy = (Inst*)malloc(sizeof(Inst));
    if (!copy) return fmi2Error;
    memcpy(copy, c, sizeof(Inst));
    *st = copy; return fmi2OK;
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate st) { memcpy(c, st, sizeof(Inst)); return fmi2OK; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate* st) { free(*st); *st = NULL; return fmi2OK; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate st, size_t* size) { return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate st, fmi2Byte b[], size_t size) { return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t size, fmi2FMUstate* st) { return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
        const fmi2ValueReference k[], size_t nk, const fmi2Real dk[], fmi2Real du[]) { return fmi2Error; }

/* ---- Model Exchange ---- */
fmi2Status fmi2EnterEventMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo* ei) {
    Inst *s = (Inst*)c;
    ei->newDiscreteStatesNeeded = fmi2False;
    ei->terminateSimulation = fmi2False;
    ei->nominalsOfContinuousStatesChanged = fmi2False;
    ei->valuesOfContinuousStatesChanged = fmi2False;
    if (s->r[VR_H] <= 0 && s->r[VR_V] < 0) {
        s->r[VR_V] = -s->r[VR_E] * s->r[VR_V];
        s->r[VR_N_BOUNCES] += 1;
        ei->valuesOfContinuousStatesChanged = fmi2True;
    }
    if (!s->time_event_done && s->r[VR_T_SWITCH] >= 0 && s->time >= s->r[VR_T_SWITCH]) {
        s->r[VR_G_NOW] = s->r[VR_G2];
        s->time_event_done = 1;
    }
    if (s->step_event_pending) { s->r[VR_N_STEP_EVENTS] += 1; s->step_event_pending = 0; }
    ei->nextEventTimeDefined = (!s->time_event_done && s->r[VR_T_SWITCH] >= 0) ? fmi2True : fmi2False;
    ei->nextEventTime = s->r[VR_T_SWITCH];
    derivs(s);
    return fmi2OK;
}
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSet, fmi2Boolean* enter, fmi2Boolean* term) {
    Inst *s = (Inst*)c;
    s->n_completed++;
    *term = fmi2False;
    *enter = fmi2False;
    long every = (long)s->r[VR_STEP_EVERY];
    if (every > 0 && s->n_completed % every == 0) { s->step_event_pending = 1; *enter = fmi2True; }
    return fmi2OK;
}
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) { ((Inst*)c)->time = t; return fmi2OK; }
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    Inst *s = (Inst*)c;
    if (nx != 3) return fmi2Error;
    s->r[VR_H] = x[0]; s->r[VR_V] = x[1]; s->r[VR_X] = x[2]; return fmi2OK;
}
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    Inst *s = (Inst*)c; derivs(s);
    if (nx != 3) return fmi2Error;
    dx[0] = s->r[VR_DER_H]; dx[1] = s->r[VR_DER_V]; dx[2] = s->r[VR_DER_X]; return fmi2OK;
}
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz) {
    if (nz != 1) return fmi2Error;
    z[0] = ((Inst*)c)->r[VR_H]; return fmi2OK;
}
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    Inst *s = (Inst*)c;
    if (nx != 3) return fmi2Error;
    x[0] = s->r[VR_H]; x[1] = s->r[VR_V]; x[2] = s->r[VR_X]; return fmi2OK;
}
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real xn[], size_t nx) {
    for (size_t i = 0; i < nx; i++) xn[i] = 1.0; return fmi2OK;
}

/* ---- Co-Simulation ---- */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], const fmi2Real v[]) { return fmi2Error; }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], fmi2Real v[]) { return fmi2Error; }
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    Inst *s = (Inst*)c;
    if (h > s->r[VR_DISCARD_ABOVE]) {
        char msg[160];
        snprintf(msg, sizeof msg, "step size %g s is larger than discard_above = %g s: discarded", h, s->r[VR_DISCARD_ABOVE]);
        logmsg(s, fmi2Discard, "logStatusDiscard", msg);
        return fmi2Discard;
    }
    s->r[VR_X] += s->r[VR_U] * h;
    s->r[VR_N_STEPS_DONE] += 1;
    s->time = t + h;
    return fmi2OK;
}
fmi2Status fmi2CancelStep(fmi2Component c) { return fmi2Error; }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status* v) { return fmi2Error; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real* v) {
    if (k == fmi2LastSuccessfulTime) { *v = ((Inst*)c)->time; return fmi2OK; }
    return fmi2Error;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer* v) { return fmi2Error; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean* v) { return fmi2Error; }
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String* v) { return fmi2Error; }
