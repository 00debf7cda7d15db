"""A C FMU that ends the simulation itself (FMI 2.0 co-simulation): a mass pushed by a
constant force that ends the run at T_end, with an Enumeration parameter.  Built once a
session by the ``ender`` fixture (tests/conftest.py)."""
from __future__ import annotations

import zipfile
from pathlib import Path

from tests.support.third_party.build import Variable, compile_library, model_description

#: FMI 2.0 co-simulation, a mass under a constant force F plus the port force P.f_x,
#: integrated exactly over each step (the force held): x = x0 + v t + F t^2 / (2 m).  At
#: t = T_end it ends the simulation as the standard says: the step that reaches T_end
#: advances to T_end only, returns fmi2Discard, and fmi2GetBooleanStatus(fmi2Terminated)
#: is true, fmi2GetRealStatus(fmi2LastSuccessfulTime) T_end.  T_end at the start time
#: ends it as it leaves initialization (fmi2ExitInitializationMode returns fmi2Discard,
#: its status terminated).
ENDER_C = r"""
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

enum { M, F, T_END, FX, UX, VX, AX, N };
typedef struct { double r[N]; int direction; double time; int terminated; } Model;

/* direction (an Enumeration): 1 Push (F pushes), 2 Pull (F pulls) */
static void accelerate(Model *m) {
    m->r[AX] = ((m->direction == 2 ? -1.0 : 1.0) * m->r[F] + m->r[FX]) / m->r[M];
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n,
                               const fmi2String k[]) { return fmi2OK; }
fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                              fmi2String res, const fmi2CallbackFunctions *f,
                              fmi2Boolean visible, fmi2Boolean logging) {
    Model *m = calloc(1, sizeof(Model));
    m->r[M] = 1.0; m->r[F] = 0.0; m->r[T_END] = 1e300; m->direction = 1;
    return m;
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean td, fmi2Real tol, fmi2Real t0,
                               fmi2Boolean sd, fmi2Real stop) {
    ((Model *)c)->time = t0; return fmi2OK;
}
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Model *m = c;
    accelerate(m);
    /* T_end at the start: ended as it leaves initialization (status fmi2Terminated) */
    if (m->r[T_END] <= m->time) { m->terminated = 1; return fmi2Discard; }
    return fmi2OK;
}
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       fmi2Real v[]) {
    Model *m = c;
    for (size_t k = 0; k < n; k++) { if (vr[k] >= N) return fmi2Error; v[k] = m->r[vr[k]]; }
    return fmi2OK;
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       const fmi2Real v[]) {
    Model *m = c;
    for (size_t k = 0; k < n; k++) { if (vr[k] >= N) return fmi2Error; m->r[vr[k]] = v[k]; }
    accelerate(m);
    return fmi2OK;
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          fmi2Integer v[]) {
    for (size_t k = 0; k < n; k++) { if (vr[k]) return fmi2Error; v[k] = ((Model *)c)->direction; }
    return fmi2OK;
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Integer v[]) {
    for (size_t k = 0; k < n; k++) {
        if (vr[k] || v[k] < 1 || v[k] > 2) return fmi2Error;
        ((Model *)c)->direction = v[k];
    }
    accelerate(c);
    return fmi2OK;
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         fmi2String v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         const fmi2String v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) {
    if (!*s) *s = malloc(sizeof(Model));
    memcpy(*s, c, sizeof(Model)); return fmi2OK;
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) {
    memcpy(c, s, sizeof(Model)); return fmi2OK;
}
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) {
    free(*s); *s = NULL; return fmi2OK;
}
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) {
    return fmi2Error;
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) {
    return fmi2Error;
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n,
                                   fmi2FMUstate *s) { return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[],
        size_t nu, const fmi2ValueReference z[], size_t nz, const fmi2Real du[],
        fmi2Real dz[]) { return fmi2Error; }
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
        size_t n, const fmi2Integer o[], const fmi2Real v[]) { return fmi2Error; }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
        size_t n, const fmi2Integer o[], fmi2Real v[]) { return fmi2Error; }
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean prior) {
    Model *m = c;
    if (m->terminated) return fmi2Error;  /* no step after the end */
    double end = t + h, d;
    int ends = end >= m->r[T_END] - 1e-12;
    d = (ends ? m->r[T_END] : end) - t;
    accelerate(m);
    m->r[UX] += m->r[VX] * d + 0.5 * m->r[AX] * d * d;
    m->r[VX] += m->r[AX] * d;
    m->time = t + d;
    if (ends) { m->terminated = 1; return fmi2Discard; }
    return fmi2OK;
}
fmi2Status fmi2CancelStep(fmi2Component c) { return fmi2Error; }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v) {
    return fmi2Discard;
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v) {
    if (s != fmi2LastSuccessfulTime) return fmi2Discard;
    *v = ((Model *)c)->time; return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v) {
    return fmi2Discard;
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v) {
    if (s != fmi2Terminated) return fmi2Discard;
    *v = ((Model *)c)->terminated; return fmi2OK;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v) {
    return fmi2Discard;
}
"""


ENDER_VARIABLES = (
    Variable("m", 0, causality="parameter", start=1.0),
    Variable("F", 1, causality="parameter", start=0.0),
    Variable("T_end", 2, causality="parameter", start=1e300),
    Variable("P.f_x", 3, causality="input", start=0.0),
    Variable("P.u_x", 4, causality="output", initial="exact", start=0.0),
    Variable("P.v_x", 5, causality="output", initial="exact", start=0.0),
    Variable("P.a_x", 6, causality="output", initial="calculated"),
    Variable("direction", 0, "Enumeration", "parameter", start=1),
)


#: the enumeration type of ``direction`` (FMI 2.0 needs one declared)
DIRECTION = ('<TypeDefinitions><SimpleType name="Direction"><Enumeration>'
             '<Item name="Push" value="1"/><Item name="Pull" value="2"/>'
             "</Enumeration></SimpleType></TypeDefinitions>")


def build_ender(folder: Path) -> Path:
    """The FMU of ENDER_C in ``folder``, compiled with gcc against fmpy's FMI 2.0 headers."""
    source = folder / "ender.c"
    source.write_text(ENDER_C)
    library = compile_library(source, folder / "ender.so")
    fmu = folder / "ender.fmu"
    with zipfile.ZipFile(fmu, "w") as archive:
        description = model_description("ender", ENDER_VARIABLES).replace(
            "<ModelVariables>", DIRECTION + "<ModelVariables>").replace(
            '<Enumeration start="1"/>', '<Enumeration declaredType="Direction" start="1"/>')
        archive.writestr("modelDescription.xml", description)
        archive.write(library, "binaries/linux64/ender.so")
    return fmu
