/* The FMI 2.0 co-simulation interface of the boom drive's native FMU (docs/fmu.md).
 *
 * Written once for every export: what the drive computes is the model's own code as numba
 * compiled it, linked in as one object file whose entry point is boom_native (fmu/native.py:
 * the parameters' derivations, the stepping loop with its stability substeps and energy
 * guard, the outputs, the geometry). This file keeps an instance's state and time, checks
 * what a host sets, and answers the FMI calls. What an export adds, its variables and its
 * parameters, comes from the header export.py writes beside it (boom_drive_model.h).
 *
 * A communication step of h seconds takes h / time_step_s steps with the valve command,
 * the payload and the external rod force held over it. A step the drive cannot take is
 * refused (fmi2Discard): one not starting at the FMU's time, a step size that is not a
 * whole number of time steps, a value out of range, a step the simulation cannot finish
 * (energy balance broken, too stiff, the rod out of the geometry); the FMU stays at the
 * step's start (fmi2LastSuccessfulTime) and logs the reason in one line. Bad input never
 * gives fmi2Fatal. fmi2Reset goes back to the exported parameters, at rest.
 */
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* --- FMI 2.0 types (fmi2TypesPlatform.h, fmi2FunctionTypes.h) ---------------------------- */
typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;
#define fmi2True 1
#define fmi2False 0

typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated } fmi2StatusKind;

typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
typedef void *(*fmi2CallbackAllocateMemory)(size_t, size_t);
typedef void (*fmi2CallbackFreeMemory)(void *);
typedef void (*fmi2StepFinished)(fmi2ComponentEnvironment, fmi2Status);
typedef struct {
    fmi2CallbackLogger logger;
    fmi2CallbackAllocateMemory allocateMemory;
    fmi2CallbackFreeMemory freeMemory;
    fmi2StepFinished stepFinished;
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

#define EXPORT __attribute__((visibility("default")))

#include "boom_drive_model.h"

/* --- the compiled model (fmu/native.py) ------------------------------------------------- */
extern int32_t boom_native(int32_t op, double *a, double *b, double *c, double *d) __asm__(BOOM_NATIVE_SYMBOL);
/* The stepping's outcomes (solve/stepping.py, solve/outcomes.py). */
enum { OUTCOME_OK, OUTCOME_NONFINITE, OUTCOME_ENERGY, OUTCOME_TOO_STIFF, OUTCOME_GEOMETRY };

/* The compiled code calls these only where it raised (its error path, which would hand a
 * Python exception to Python): here they note that it did, and do nothing else. */
static __thread int raised;
void *numba_gil_ensure(void) { raised = 1; return NULL; }
void numba_gil_release(void *state) { (void)state; }
void *numba_unpickle(const char *data, int n, const char *hashed) { (void)data; (void)n; (void)hashed; raised = 1; return NULL; }
void *numba_runtime_build_excinfo_struct(void *a, void *b) { (void)a; (void)b; raised = 1; return NULL; }
int numba_do_raise(void *exc) { (void)exc; raised = 1; return 0; }

/* numba's runtime (NRT), as much of it as the compiled model calls: ros2's stages are arrays
 * and its state a list, which it allocates and releases through these (the layout and the
 * behaviour of numba's nrt.cpp, on malloc and free). The others allocate nothing. */
typedef void (*NRT_dtor_function)(void *ptr, size_t size, void *info);
typedef struct {
    size_t refct; /* compiled code counts references on this first field */
    NRT_dtor_function dtor;
    void *dtor_info;
    void *data;
    size_t size;
    void *external_allocator;
} NRT_MemInfo;

void *NRT_Allocate(size_t size) { return malloc(size); }
void *NRT_Reallocate(void *ptr, size_t size) { return realloc(ptr, size); }
void NRT_Free(void *ptr) { free(ptr); }

static void nrt_init(NRT_MemInfo *mi, void *data, size_t size, NRT_dtor_function dtor, void *dtor_info) {
    mi->refct = 1;
    mi->dtor = dtor;
    mi->dtor_info = dtor_info;
    mi->data = data;
    mi->size = size;
    mi->external_allocator = NULL;
}

NRT_MemInfo *NRT_MemInfo_alloc_aligned(size_t size, unsigned align) {
    char *base = (char *)malloc(sizeof(NRT_MemInfo) + size + 2 * (size_t)align);
    if (!base) return NULL;
    char *data = base + sizeof(NRT_MemInfo);
    size_t remainder = align ? (size_t)data % align : 0;
    if (remainder) data += align - remainder;
    nrt_init((NRT_MemInfo *)base, data, size, NULL, NULL);
    return (NRT_MemInfo *)base;
}

static void nrt_varsize_dtor(void *ptr, size_t size, void *info) {
    (void)size;
    if (info) ((void (*)(void *))info)(ptr); /* the elements' destructor */
    free(ptr);
}

NRT_MemInfo *NRT_MemInfo_new_varsize_dtor(size_t size, NRT_dtor_function dtor) {
    NRT_MemInfo *mi = (NRT_MemInfo *)malloc(sizeof(NRT_MemInfo));
    void *data = malloc(size);
    if (!mi || !data) {
        free(mi);
        free(data);
        return NULL;
    }
    nrt_init(mi, data, size, nrt_varsize_dtor, (void *)dtor);
    return mi;
}

void *NRT_MemInfo_varsize_alloc(NRT_MemInfo *mi, size_t size) {
    mi->data = malloc(size);
    if (mi->data) mi->size = size;
    return mi->data;
}

void *NRT_MemInfo_varsize_realloc(NRT_MemInfo *mi, size_t size) {
    mi->data = realloc(mi->data, size);
    if (mi->data) mi->size = size;
    return mi->data;
}

void NRT_MemInfo_varsize_free(NRT_MemInfo *mi, void *ptr) {
    free(ptr);
    if (ptr == mi->data) mi->data = NULL;
}

void NRT_MemInfo_call_dtor(NRT_MemInfo *mi) {
    if (mi->dtor) mi->dtor(mi->data, mi->size, mi->dtor_info);
    free(mi); /* the MemInfo, and with it the data allocated after it */
}

void *PyBytes_FromStringAndSize(const char *s, ptrdiff_t n) { (void)s; (void)n; return NULL; }
void PyErr_Clear(void) {}
void PyErr_SetNone(void *type) { (void)type; raised = 1; }
void PyErr_SetString(void *type, const char *message) { (void)type; (void)message; raised = 1; }
void PyErr_WriteUnraisable(void *obj) { (void)obj; raised = 1; }
void *PyUnicode_FromString(const char *s) { (void)s; return NULL; }
void Py_DecRef(void *obj) { (void)obj; }
void *PyExc_RuntimeError, *PyExc_StopIteration, *PyExc_SystemError;

/* One call of the compiled model: its result, or -1 where it raised. */
static int native(int op, double *a, double *b, double *c, double *d) {
    raised = 0;
    int32_t result = boom_native(op, a, b, c, d);
    return (raised || result == 0) ? -1 : result - 1;
}

/* ``value`` as Python's repr writes a float: the fewest digits that read back as the same
 * double, positional from 1e-4 to 1e16 (with ".0" where it is whole), else with an exponent. */
typedef struct { char text[40]; } Number;
static Number number(double value) {
    Number n;
    if (isnan(value) || isinf(value)) {
        snprintf(n.text, sizeof n.text, "%s", isnan(value) ? "nan" : value > 0 ? "inf" : "-inf");
        return n;
    }
    char e[40];
    int digits = 1;
    for (; digits < 17; digits++) {
        snprintf(e, sizeof e, "%.*e", digits - 1, value);
        if (strtod(e, NULL) == value) break;
    }
    snprintf(e, sizeof e, "%.*e", digits - 1, value);
    int exponent = atoi(strchr(e, 'e') + 1);
    if (exponent < -4 || exponent >= 16) {
        snprintf(n.text, sizeof n.text, "%s", e);
        return n;
    }
    int decimals = digits - 1 - exponent;
    snprintf(n.text, sizeof n.text, "%.*f", decimals > 0 ? decimals : 0, value);
    if (!strchr(n.text, '.')) strncat(n.text, ".0", sizeof n.text - strlen(n.text) - 1);
    return n;
}
#define NUM(x) (number(x).text)

/* --- an instance --------------------------------------------------------------------------- */
typedef struct {
    fmi2CallbackFunctions callbacks;
    char name[256];
    int logging;
    double active[N_ROW]; /* the parameters in effect */
    double next[N_ROW];   /* ... with what the host set since (in effect from the next step) */
    double valve;         /* the input valve_command */
    double y[N_STATE];
    double c[N_CONSTANTS];
    double energy_base; /* H - W that the energy balance keeps, J */
    double t, t_base;   /* the drive's time, s: t_base + (count - n_base) dt */
    long long count, n_base;
    double u; /* the command of the last step */
    double start_s;
    int initialized;
    char stopped[2048]; /* why no step can be taken ("" when one can) */
    double outputs[N_OUTPUTS];
    char text[N_ROW][64]; /* the strings fmi2GetString hands out */
} Instance;

static void say(Instance *m, fmi2Status status, const char *category, const char *format, ...) {
    char line[2048];
    va_list args;
    va_start(args, format);
    vsnprintf(line, sizeof line, format, args);
    va_end(args);
    for (char *p = line; *p; p++)
        if (*p == '\n') *p = ' ';
    if (m->callbacks.logger) m->callbacks.logger(m->callbacks.componentEnvironment, m->name, status, category, "%s", line);
}

static void at_rest_outputs(Instance *m) {
    for (int i = 0; i < N_OUTPUTS; i++) m->outputs[i] = NAN;
}

static void restart(Instance *m) {
    memcpy(m->active, EXPORTED_ROW, sizeof m->active);
    memcpy(m->next, EXPORTED_ROW, sizeof m->next);
    m->valve = 0.0;
    m->initialized = 0;
    m->start_s = 0.0;
    snprintf(m->stopped, sizeof m->stopped, "the FMU is not initialized yet: enter and exit initialization mode first");
    at_rest_outputs(m);
}

/* The value of string entry ``k`` of ``row``, among its choices ("" for none). */
static const char *text_of(int k, const double *row) {
    const RowCheck *r = &ROW_CHECKS[k];
    double code = row[k];
    return (code >= 0 && code < r->n_choices) ? r->choices[(int)code] : "";
}

/* Whether the plant's parameters in ``row`` fit together: the model's own checks, compiled
 * (model/parameters.py, plant_fault); where one fails, its line (PLANT_FAULTS, as export.py
 * wrote its pieces: text, and the value it names as Python writes it) in ``why``, and 1. */
static int cross_check(const double *row, char *why, size_t size) {
    double limits[N_LIMITS];
    int fault = native(OP_PLANT_FAULT, (double *)row, limits, NULL, NULL);
    if (fault == 0) return 0;
    if (fault < 0 || fault > N_PLANT_FAULTS) {
        snprintf(why, size, "the model's checks of the parameters could not be evaluated");
        return 1;
    }
    size_t used = 0;
    why[0] = '\0';
    for (int i = 0; i < PLANT_FAULT_PIECES[fault - 1] && used < size; i++) {
        const Piece *piece = &PLANT_FAULTS[fault - 1][i];
        char value[64] = "";
        double v = piece->source == SOURCE_ROW ? row[piece->index] : piece->source == SOURCE_LIMIT ? limits[piece->index] : 0.0;
        if (piece->source == SOURCE_ROW && ROW_CHECKS[piece->index].n_choices > 0)
            snprintf(value, sizeof value, "%s", text_of(piece->index, row));
        else if (piece->source != SOURCE_NONE && piece->format)
            snprintf(value, sizeof value, piece->format, v);
        else if (piece->source != SOURCE_NONE)
            snprintf(value, sizeof value, "%s", NUM(v));
        used += snprintf(why + used, size - used, "%s%s", piece->text, value);
    }
    return 1;
}

/* Why the row ``row`` cannot run (written to ``why``), or 0 where it can: every entry in its
 * range (parameters.py's), the strings among their choices (``texts``: the strings set);
 * the model's cross checks. In parameters.py's words. */
static int refused_row(const double *row, const char (*texts)[64], char *why, size_t size) {
    for (int k = 0; k < N_ROW; k++) {
        const RowCheck *r = &ROW_CHECKS[k];
        double v = row[k];
        if (r->n_choices > 0) {
            if (!(v >= 0.0 && v < r->n_choices && v == floor(v))) {
                snprintf(why, size, "parameter '%s' is '%s'; choose one of %s", ROW_NAMES[k], texts[k], r->choice_list);
                return 1;
            }
            continue;
        }
        char text[48];
        if (r->is_int)
            snprintf(text, sizeof text, "%.0f", v);
        else
            snprintf(text, sizeof text, "%s", NUM(v));
        if (!isfinite(v)) {
            snprintf(why, size, "parameter '%s' must be finite, got %s", ROW_NAMES[k], text);
            return 1;
        }
        if (r->has_low && (r->low_inclusive ? v < r->low : v <= r->low)) {
            snprintf(why, size, "parameter '%s' (%s) is %s%s; it must be %s %s", ROW_NAMES[k], r->description, text, r->unit,
                     r->low_inclusive ? ">=" : ">", r->low_text);
            return 1;
        }
        if (r->has_high && v > r->high) {
            snprintf(why, size, "parameter '%s' is %s%s; it must be <= %s", ROW_NAMES[k], text, r->unit, r->high_text);
            return 1;
        }
    }
    return cross_check(row, why, size);
}

/* The state at rest, the constants and the energy balance's base of row ``next``. */
static int begin(Instance *m) {
    if (native(OP_CONSTANTS, m->next, m->c, NULL, NULL) < 0 || native(OP_INITIAL_STATE, m->next, m->y, NULL, NULL) < 0)
        return -1;
    memcpy(m->active, m->next, sizeof m->active);
    m->t = m->t_base = 0.0;
    m->count = m->n_base = 0;
    m->u = 0.0;
    double h = 0.0;
    if (native(OP_ENERGY, m->y, m->c, NULL, &h) < 0) return -1;
    m->energy_base = 0.0;
    m->energy_base = h - m->y[ENERGY_INDEX] - m->energy_base; /* H - W at rest: the balance starts at zero */
    return 0;
}

static int observe(Instance *m) {
    double tu[2] = {m->t, m->u};
    return native(OP_OUTPUTS, m->y, m->c, tu, m->outputs);
}

/* --- FMI: the instance's life ----------------------------------------------------------- */
EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                     fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                                     fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)fmuResourceLocation;
    (void)visible;
    Instance probe;
    memset(&probe, 0, sizeof probe);
    if (functions) probe.callbacks = *functions;
    snprintf(probe.name, sizeof probe.name, "%s", instanceName ? instanceName : "");
    if (fmuType != fmi2CoSimulation) {
        say(&probe, fmi2Error, "logStatusError", "this FMU is for co-simulation only");
        return NULL;
    }
    if (fmuGUID && *fmuGUID && strcmp(fmuGUID, MODEL_GUID) != 0) {
        say(&probe, fmi2Error, "logStatusError", "GUID %s is not this FMU's (%s): its binary and model description differ",
            fmuGUID, MODEL_GUID);
        return NULL;
    }
    Instance *m = (Instance *)calloc(1, sizeof(Instance));
    if (!m) return NULL;
    *m = probe;
    m->logging = loggingOn;
    restart(m);
    return m;
}

EXPORT void fmi2FreeInstance(fmi2Component c) { free(c); }

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t n, const fmi2String categories[]) {
    (void)n;
    (void)categories;
    ((Instance *)c)->logging = loggingOn;
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                                      fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    Instance *m = (Instance *)c;
    if (!isfinite(startTime)) {
        say(m, fmi2Error, "logStatusError", "start time %g is not finite", startTime);
        return fmi2Error;
    }
    m->start_s = startTime;
    return fmi2OK;
}

EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }

EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *m = (Instance *)c;
    char why[1024];
    if (refused_row(m->next, (const char (*)[64])m->text, why, sizeof why)) {
        snprintf(m->stopped, sizeof m->stopped, "initialization refused: %s", why);
        say(m, fmi2Error, "logStatusError", "%s", m->stopped);
        return fmi2Error;
    }
    if (begin(m) < 0 || observe(m) < 0) {
        snprintf(m->stopped, sizeof m->stopped, "initialization refused: the model cannot be evaluated at rest with these parameters");
        say(m, fmi2Error, "logStatusError", "%s", m->stopped);
        return fmi2Error;
    }
    m->initialized = 1;
    m->stopped[0] = '\0';
    return fmi2OK;
}

EXPORT fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *m = (Instance *)c;
    m->initialized = 0;
    snprintf(m->stopped, sizeof m->stopped, "the FMU is terminated: reset it to run again");
    return fmi2OK;
}

EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    restart((Instance *)c);
    return fmi2OK;
}

/* --- FMI: values -------------------------------------------------------------------------- */
static const Variable *variable(Instance *m, fmi2ValueReference vr, int kind) {
    if (vr >= N_VARIABLES || VARIABLES[vr].kind != kind) {
        say(m, fmi2Error, "logStatusError", "value reference %u is no %s variable of this FMU", vr,
            kind == KIND_REAL ? "Real" : kind == KIND_INTEGER ? "Integer" : "String");
        return NULL;
    }
    return &VARIABLES[vr];
}

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    Instance *m = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        const Variable *v = variable(m, vr[i], KIND_REAL);
        if (!v) return fmi2Error;
        value[i] = v->role == ROLE_VALVE ? m->valve : v->role == ROLE_OUTPUT ? m->outputs[v->index] : m->next[v->index];
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer value[]) {
    Instance *m = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        const Variable *v = variable(m, vr[i], KIND_INTEGER);
        if (!v) return fmi2Error;
        value[i] = (fmi2Integer)m->next[v->index];
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[]) {
    (void)value;
    if (n > 0) {
        say((Instance *)c, fmi2Error, "logStatusError", "value reference %u: this FMU has no Boolean variables", vr[0]);
        return fmi2Error;
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String value[]) {
    Instance *m = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        const Variable *v = variable(m, vr[i], KIND_STRING);
        if (!v) return fmi2Error;
        const RowCheck *r = &ROW_CHECKS[v->index];
        double code = m->next[v->index];
        const char *text = (code >= 0 && code < r->n_choices) ? r->choices[(int)code] : m->text[v->index];
        value[i] = text;
    }
    return fmi2OK;
}

/* A value set for a variable: the valve command, or the entry of the parameters' row (a
 * fixed parameter only before initialization ends, or to the value it has). */
static fmi2Status set_row(Instance *m, const Variable *v, double value) {
    if (v->role == ROLE_OUTPUT) {
        say(m, fmi2Error, "logStatusError", "%s is an output: it cannot be set", v->name);
        return fmi2Error;
    }
    if (v->role == ROLE_CALCULATED) {
        say(m, fmi2Error, "logStatusError", "%s is the one this FMU was exported with (%s): its step is compiled in; "
            "export the FMU again with boom-sim fmu --set %s=... for another", v->name, text_of(v->index, m->active), v->name);
        return fmi2Error;
    }
    if (v->role == ROLE_VALVE)
        m->valve = value;
    else
        m->next[v->index] = value;
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    Instance *m = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        const Variable *v = variable(m, vr[i], KIND_REAL);
        if (!v || set_row(m, v, value[i]) != fmi2OK) return fmi2Error;
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer value[]) {
    Instance *m = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        const Variable *v = variable(m, vr[i], KIND_INTEGER);
        if (!v || set_row(m, v, (double)value[i]) != fmi2OK) return fmi2Error;
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean value[]) {
    (void)value;
    if (n > 0) {
        say((Instance *)c, fmi2Error, "logStatusError", "value reference %u: this FMU has no Boolean variables", vr[0]);
        return fmi2Error;
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String value[]) {
    Instance *m = (Instance *)c;
    for (size_t i = 0; i < n; i++) {
        const Variable *v = variable(m, vr[i], KIND_STRING);
        if (!v) return fmi2Error;
        const RowCheck *r = &ROW_CHECKS[v->index];
        double code = NAN; /* a value that is none of the choices: refused at the next step */
        for (int j = 0; j < r->n_choices; j++)
            if (value[i] && strcmp(value[i], r->choices[j]) == 0) code = j;
        if (set_row(m, v, code) != fmi2OK) return fmi2Error;
        snprintf(m->text[v->index], sizeof m->text[v->index], "%s", value[i] ? value[i] : "");
    }
    return fmi2OK;
}

/* --- FMI: stepping ------------------------------------------------------------------------ */
/* What to change where the integration diverged (solve/outcomes.py, step_advice). */
static void step_advice(const Instance *m, char *text, size_t size) {
    const char *method = text_of(ROW_method, m->active);
    double dt = m->active[ROW_TIME_STEP];
    if (HALVING)
        snprintf(text, size, "the integration diverged: the step of %g s (%s, taken again in up to %d substeps) is too large "
                 "for these parameters; try a smaller time_step_s, or method rk4 (its stability bound sizes its substeps)",
                 dt, method, HALVED_MOST);
    else
        snprintf(text, size, "the integration diverged: the step of %g s (%s, at least %.0f substeps) is too large for these "
                 "parameters; try a smaller time_step_s or more substeps, or method ros2", dt, method, m->active[ROW_SUBSTEPS]);
}

/* Why a run stopped: ``outcome`` of the step after ``t_s`` from the last good state ``y``, in
 * the words of solve/outcomes.py (message), as boom-sim says it. */
static void failure(const Instance *m, int outcome, double t_s, const double *y, double needed, char *why, size_t size) {
    char state[256], advice[512];
    snprintf(state, sizeof state, "q1 = %.6g, v = %.6g, p1 = %.6g, p2 = %.6g, x_v = %.6g", y[0], y[1], y[2], y[3], y[4]);
    step_advice(m, advice, sizeof advice);
    double a = m->c[CONSTANT_A], b = m->c[CONSTANT_B];
    if (outcome == OUTCOME_NONFINITE)
        snprintf(why, size, "state became non-finite after t = %.6g s (the next step; last finite state %s); %s", t_s, state, advice);
    else if (outcome == OUTCOME_ENERGY)
        snprintf(why, size, "energy balance broken after t = %.6g s: the change of the stored energy no longer matches the energy "
                 "that flowed, by more than 1%% (%s); %s", t_s, state, advice);
    else if (outcome == OUTCOME_TOO_STIFF)
        snprintf(why, size, "too stiff at t = %.6g s: a stable %s step of %g s needs %.0f substeps, more than %d (%s); use method "
                 "ros2 (implicit) or larger dead volumes%s, a lower bulk_modulus_pa or a smaller orifice", t_s,
                 text_of(ROW_method, m->active), m->active[ROW_TIME_STEP], needed, MAX_SUBSTEPS, state,
                 VOLUME_ADVICE[(int)m->active[ROW_drive]]);
    else if (outcome == OUTCOME_GEOMETRY)
        snprintf(why, size, "rod left the valid geometry after t = %.6g s (%s): the next step takes q1 outside (%.4g, %.4g) m "
                 "where the triangle of eq. 1 degenerates; %s", t_s, state, fabs(b - a), a + b, advice);
    else
        snprintf(why, size, "the model cannot be evaluated near t = %.6g s (%s); %s", t_s, state, advice);
}

/* Why the parameters the host set cannot take effect at the next step, or 0: a fixed
 * parameter changed after initialization, or a value out of range. */
static int refused_changes(Instance *m, char *why, size_t size) {
    size_t used = 0;
    why[0] = '\0';
    for (int k = 0; k < N_ROW; k++) {
        int same = m->next[k] == m->active[k] || (isnan(m->next[k]) && isnan(m->active[k]));
        if (!same && ROW_FIXED[k]) used += snprintf(why + used, size - used, "%s%s", used ? ", " : "", ROW_NAMES[k]);
        if (used >= size) break;
    }
    if (used > 0 && used < size) {
        snprintf(why + used, size - used, " can only be set before initialization (variability fixed); reset the FMU to change it");
        return 1;
    }
    return refused_row(m->next, (const char (*)[64])m->text, why, size);
}

static fmi2Status refuse(Instance *m, fmi2Real t, fmi2Real h, const char *why) {
    say(m, fmi2Discard, "logStatusDiscard", "step of %s s from t = %s s refused: %s", NUM(h), NUM(t), why);
    return fmi2Discard;
}

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                             fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    Instance *m = (Instance *)c;
    double t = currentCommunicationPoint, h = communicationStepSize;
    char why[2048];
    if (!m->initialized) return refuse(m, t, h, m->stopped);
    double dt = m->active[ROW_TIME_STEP];
    double offset = t - m->start_s;
    if (!(fabs(offset - m->t) < 0.5 * dt)) {
        snprintf(why, sizeof why, "it starts %s s after the start, but the FMU is at %s s; step on from the last communication point",
                 NUM(offset), NUM(m->t));
        return refuse(m, t, h, why);
    }
    double ratio = h / dt;
    double whole = (isfinite(ratio) && h > 0) ? nearbyint(ratio) : 0.0;
    if (!(whole >= 1.0 && whole <= MAX_STEPS_AT_ONCE && fabs(whole * dt - h) <= GRID_TOLERANCE * dt)) {
        snprintf(why, sizeof why, "the step size is not a whole number of the drive's time steps of %s s (time_step_s); use a multiple of it%s",
                 NUM(dt), whole > MAX_STEPS_AT_ONCE ? " (and at most " MAX_STEPS_TEXT " of them in one step)" : "");
        return refuse(m, t, h, why);
    }
    long long steps = (long long)whole;
    if (refused_changes(m, why, sizeof why)) return refuse(m, t, h, why);
    if (!isfinite(m->valve)) {
        snprintf(why, sizeof why, "valve_command must be a finite opening in [-1, 1], got %g", m->valve);
        return refuse(m, t, h, why);
    }
    double opening = fmin(1.0, fmax(-1.0, m->valve));
    if (memcmp(m->next, m->active, sizeof m->next) != 0) { /* new parameters: the state stays, the balance carries on */
        double c_new[N_CONSTANTS], before = 0.0, after = 0.0;
        if (native(OP_CONSTANTS, m->next, c_new, NULL, NULL) < 0 || native(OP_ENERGY, m->y, m->c, NULL, &before) < 0 ||
            native(OP_ENERGY, m->y, c_new, NULL, &after) < 0)
            return refuse(m, t, h, "the model cannot be evaluated with these parameters");
        double w = m->y[ENERGY_INDEX];
        double residual = before - w - m->energy_base;
        double residual_new = after - w - m->energy_base;
        m->energy_base += residual_new - residual;
        memcpy(m->c, c_new, sizeof c_new);
        memcpy(m->active, m->next, sizeof m->active);
        m->t_base = m->t;
        m->n_base = m->count;
    }
    double y0[N_STATE];
    memcpy(y0, m->y, sizeof y0);
    double args[9] = {m->t, opening, dt, m->active[ROW_SUBSTEPS], STABILITY_LIMIT, MAX_SUBSTEPS, (double)steps,
                      ENERGY_INDEX, m->energy_base};
    double info[2] = {0.0, 0.0};
    int outcome = native(OP_STEP, m->y, m->c, args, info);
    double t_end = m->t_base + (double)(m->count + (long long)info[0] - m->n_base) * dt;
    double geometry[3] = {m->y[0], m->c[CONSTANT_A], m->c[CONSTANT_B]};
    int within = native(OP_WITHIN, geometry, NULL, NULL, NULL);
    if (outcome != OUTCOME_OK || within != 1) {
        double y_last[N_STATE]; /* the last good state of the failed step */
        memcpy(y_last, m->y, sizeof y_last);
        memcpy(m->y, y0, sizeof y0); /* the step is not taken */
        double t_last = t_end;
        if (within != 1 && outcome >= 0) { /* which step left the geometry: the steps again, one at a time (bit for bit) */
            memcpy(y_last, y0, sizeof y_last);
            for (long long k = 0; k < (long long)info[0]; k++) {
                double y_next[N_STATE], one[9], taken[2];
                memcpy(y_next, y_last, sizeof y_next);
                memcpy(one, args, sizeof one);
                one[0] = m->t + (double)k * dt;
                one[6] = 1.0;
                native(OP_STEP, y_next, m->c, one, taken);
                double q[3] = {y_next[0], m->c[CONSTANT_A], m->c[CONSTANT_B]};
                t_last = m->t_base + (double)(m->count + k - m->n_base) * dt;
                if (native(OP_WITHIN, q, NULL, NULL, NULL) != 1) break;
                memcpy(y_last, y_next, sizeof y_last);
            }
        }
        failure(m, within != 1 && outcome >= 0 ? OUTCOME_GEOMETRY : outcome, t_last, y_last, info[1], why, sizeof why);
        return refuse(m, t, h, why);
    }
    m->count += (long long)info[0];
    m->t = m->t_base + (double)(m->count - m->n_base) * dt;
    m->u = opening;
    if (observe(m) < 0) {
        say(m, fmi2Error, "logStatusError", "the outputs cannot be evaluated at t = %.6g s", m->t);
        return fmi2Error;
    }
    return fmi2OK;
}

EXPORT fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2OK; }

EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)c;
    (void)s;
    *value = fmi2OK;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    Instance *m = (Instance *)c;
    if (s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = m->start_s + m->t;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)c;
    (void)s;
    (void)value;
    return fmi2Discard;
}

EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    (void)c;
    if (s != fmi2Terminated) return fmi2Discard;
    *value = fmi2False; /* a refused step ends nothing: a shorter step from the same point can go on */
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)c;
    (void)s;
    (void)value;
    return fmi2Discard;
}

/* --- FMI: what this FMU does not offer (canGetAndSetFMUstate and the others are false) --- */
static fmi2Status not_offered(fmi2Component c, const char *what) {
    say((Instance *)c, fmi2Error, "logStatusError", "%s is not offered by this FMU (see its model description)", what);
    return fmi2Error;
}
EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return not_offered(c, "fmi2GetFMUstate"); }
EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)s; return not_offered(c, "fmi2SetFMUstate"); }
EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return not_offered(c, "fmi2FreeFMUstate"); }
EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) {
    (void)s;
    (void)n;
    return not_offered(c, "fmi2SerializedFMUstateSize");
}
EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) {
    (void)s;
    (void)b;
    (void)n;
    return not_offered(c, "fmi2SerializeFMUstate");
}
EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) {
    (void)s;
    (void)b;
    (void)n;
    return not_offered(c, "fmi2DeSerializeFMUstate");
}
EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                               const fmi2ValueReference z[], size_t nz, const fmi2Real du[], fmi2Real dz[]) {
    (void)u, (void)nu, (void)z, (void)nz, (void)du, (void)dz;
    return not_offered(c, "fmi2GetDirectionalDerivative");
}
EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                              const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr, (void)n, (void)order, (void)value;
    return not_offered(c, "fmi2SetRealInputDerivatives");
}
EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                               const fmi2Integer order[], fmi2Real value[]) {
    (void)vr, (void)n, (void)order, (void)value;
    return not_offered(c, "fmi2GetRealOutputDerivatives");
}
