/* A minimal FMI 2.0 co-simulation host, as a C user would write one: it dlopens the packaged
 * BacklashShaft library, resolves the fmi2* functions by name and drives one or many instances.
 * It times the calls and prints one machine-readable line per result:
 *
 *     @ <key> <value> [<value> ...]
 *
 * Built and run by `cargo xtask bench` (xtask/src/bench/), which also writes bench_vr.h (the
 * value references, read from each archive's modelDescription.xml: VR_<name> of BacklashShaft,
 * VR_<model>_<name> of the others, and likewise START_<model>_<name> of each Real's start value)
 * and bench_rig.h (BacklashShaft's rig, read from
 * tests/fixtures/rigs.toml: RIG_<name> of each of its values, RIG_VR and RIG_VALUE of all of
 * them), and passes the guids.
 *
 * usage: native_host <lib.so> <guid> <resource-uri> <mode> [args]
 *   suite <batches> <steps-per-batch> <belt.so> <belt-guid> <belt-resource-uri>
 *         <web.so> <web-guid> <web-resource-uri> <two-stage.so> <two-stage-guid> <two-stage-resource-uri>
 *                                       per-call costs (medians over batches) and their floors;
 *                                       beside them the event-free steps of BacklashBelt,
 *                                       BacklashWeb and BacklashTwoStage, each loaded from its own
 *                                       archive
 *   scale <steps>                       one long event-free run: time and peak RSS
 *   instances <count> <batches> <instance-steps-per-batch>
 *                                       many instances stepped round-robin
 *   piloop <seconds> <repeats>          the sampled PI loop of the fmpy and scipy benchmarks
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2Functions.h"
#include "fmi3Functions.h"
#include "bench_vr.h"
#include "bench_rig.h"

#if !defined(RIG_Kp) || !defined(RIG_Ki) || !defined(RIG_VR) || !defined(RIG_VALUE)
#error "bench_rig.h lacks BacklashShaft's rig (Kp, Ki, RIG_VR, RIG_VALUE): run through `cargo xtask bench`, which writes it from tests/fixtures/rigs.toml"
#endif

#define H 1e-3 /* communication step [s] */

/* ---- the FMI 2.0 API of one loaded library ---- */

typedef struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetDebugLoggingTYPE *set_debug_logging;
    fmi2SetupExperimentTYPE *setup_experiment;
    fmi2EnterInitializationModeTYPE *enter_init;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2TerminateTYPE *terminate;
    fmi2SetRealTYPE *set_real;
    fmi2GetRealTYPE *get_real;
    fmi2GetIntegerTYPE *get_integer;
    fmi2DoStepTYPE *do_step;
    /* Model Exchange */
    fmi2NewDiscreteStatesTYPE *new_discrete_states;
    fmi2EnterContinuousTimeModeTYPE *enter_continuous_time_mode;
    fmi2SetTimeTYPE *set_time;
    fmi2SetContinuousStatesTYPE *set_continuous_states;
    fmi2GetDerivativesTYPE *get_derivatives;
    fmi2GetEventIndicatorsTYPE *get_event_indicators;
    /* FMI 3.0 Co-Simulation, for the FMI 3.0 step */
    fmi3InstantiateCoSimulationTYPE *instantiate3;
    fmi3EnterInitializationModeTYPE *enter_init3;
    fmi3ExitInitializationModeTYPE *exit_init3;
    fmi3SetFloat64TYPE *set_float64;
    fmi3DoStepTYPE *do_step3;
    fmi3FreeInstanceTYPE *free_instance3;
} Api;

/* BacklashShaft's library (the first argument), which every mode but the other drives' rows uses. */
static Api api;
static const char *guid, *resources;

static void die(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "native_host: ");
    vfprintf(stderr, fmt, ap);
    fprintf(stderr, "\n");
    va_end(ap);
    exit(1);
}

static void *symbol(void *lib, const char *name) {
    void *f = dlsym(lib, name);
    if (!f) die("%s not exported: %s", name, dlerror());
    return f;
}

/* Resolves the functions of the library at `path` into `a`. */
static void load(Api *a, const char *path) {
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) die("dlopen %s: %s", path, dlerror());
    a->instantiate = (fmi2InstantiateTYPE *)symbol(lib, "fmi2Instantiate");
    a->free_instance = (fmi2FreeInstanceTYPE *)symbol(lib, "fmi2FreeInstance");
    a->set_debug_logging = (fmi2SetDebugLoggingTYPE *)symbol(lib, "fmi2SetDebugLogging");
    a->setup_experiment = (fmi2SetupExperimentTYPE *)symbol(lib, "fmi2SetupExperiment");
    a->enter_init = (fmi2EnterInitializationModeTYPE *)symbol(lib, "fmi2EnterInitializationMode");
    a->exit_init = (fmi2ExitInitializationModeTYPE *)symbol(lib, "fmi2ExitInitializationMode");
    a->terminate = (fmi2TerminateTYPE *)symbol(lib, "fmi2Terminate");
    a->set_real = (fmi2SetRealTYPE *)symbol(lib, "fmi2SetReal");
    a->get_real = (fmi2GetRealTYPE *)symbol(lib, "fmi2GetReal");
    a->get_integer = (fmi2GetIntegerTYPE *)symbol(lib, "fmi2GetInteger");
    a->do_step = (fmi2DoStepTYPE *)symbol(lib, "fmi2DoStep");
    a->new_discrete_states = (fmi2NewDiscreteStatesTYPE *)symbol(lib, "fmi2NewDiscreteStates");
    a->enter_continuous_time_mode = (fmi2EnterContinuousTimeModeTYPE *)symbol(lib, "fmi2EnterContinuousTimeMode");
    a->set_time = (fmi2SetTimeTYPE *)symbol(lib, "fmi2SetTime");
    a->set_continuous_states = (fmi2SetContinuousStatesTYPE *)symbol(lib, "fmi2SetContinuousStates");
    a->get_derivatives = (fmi2GetDerivativesTYPE *)symbol(lib, "fmi2GetDerivatives");
    a->get_event_indicators = (fmi2GetEventIndicatorsTYPE *)symbol(lib, "fmi2GetEventIndicators");
    a->instantiate3 = (fmi3InstantiateCoSimulationTYPE *)symbol(lib, "fmi3InstantiateCoSimulation");
    a->enter_init3 = (fmi3EnterInitializationModeTYPE *)symbol(lib, "fmi3EnterInitializationMode");
    a->exit_init3 = (fmi3ExitInitializationModeTYPE *)symbol(lib, "fmi3ExitInitializationMode");
    a->set_float64 = (fmi3SetFloat64TYPE *)symbol(lib, "fmi3SetFloat64");
    a->do_step3 = (fmi3DoStepTYPE *)symbol(lib, "fmi3DoStep");
    a->free_instance3 = (fmi3FreeInstanceTYPE *)symbol(lib, "fmi3FreeInstance");
}

static void check3(fmi3Status s, const char *what) {
    if (s != fmi3OK) die("%s returned status %d", what, (int)s);
}

/* Contact-switch messages seen by the logger (category logContactEvents); other messages are
 * errors or warnings and are shown. */
static long contact_messages;

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env;
    if (category && strcmp(category, "logContactEvents") == 0) {
        contact_messages++;
        return;
    }
    va_list ap;
    va_start(ap, message);
    fprintf(stderr, "[%s] %s (status %d): ", instance ? instance : "?", category ? category : "?", (int)status);
    vfprintf(stderr, message, ap);
    fprintf(stderr, "\n");
    va_end(ap);
}

static const fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};

static void check(fmi2Status s, const char *what) {
    if (s != fmi2OK) die("%s returned status %d", what, (int)s);
}

/* ---- clocks and statistics ---- */

static double clock_ns(clockid_t id) {
    struct timespec ts;
    clock_gettime(id, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

/* Both clocks: wall (CLOCK_MONOTONIC) and this thread's CPU time, which leaves out the time the
 * thread waited for a core while other jobs ran (the machine is shared). */
typedef struct {
    double wall, cpu;
} Tic;

static Tic tic(void) { return (Tic){clock_ns(CLOCK_MONOTONIC), clock_ns(CLOCK_THREAD_CPUTIME_ID)}; }

/* Time per item since `start` [ns] into cpu[b] and wall[b]. */
static void toc(Tic start, double items, double *cpu, double *wall, int b) {
    Tic end = tic();
    cpu[b] = (end.cpu - start.cpu) / items;
    wall[b] = (end.wall - start.wall) / items;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Quantile by linear interpolation between order statistics (q in [0, 1]). */
static double quantile(const double *sorted, int n, double q) {
    double pos = q * (n - 1);
    int lo = (int)floor(pos);
    int hi = lo + 1 < n ? lo + 1 : lo;
    return sorted[lo] + (pos - lo) * (sorted[hi] - sorted[lo]);
}

/* Prints "@ <key> <median> <q1> <q3> <wall median> <wall q1> <wall q3>" for per-item times [ns]
 * over n batches: CPU time first, then wall-clock time. */
static void report(const char *key, double *cpu, double *wall, int n) {
    qsort(cpu, n, sizeof(double), cmp_double);
    qsort(wall, n, sizeof(double), cmp_double);
    printf("@ %s %.6g %.6g %.6g %.6g %.6g %.6g\n", key, quantile(cpu, n, 0.5), quantile(cpu, n, 0.25),
           quantile(cpu, n, 0.75), quantile(wall, n, 0.5), quantile(wall, n, 0.25), quantile(wall, n, 0.75));
    fflush(stdout);
}

static long status_kb(const char *field) {
    FILE *f = fopen("/proc/self/status", "r");
    if (!f) return -1;
    char line[256];
    long kb = -1;
    size_t len = strlen(field);
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, field, len) == 0 && line[len] == ':') {
            kb = strtol(line + len + 1, NULL, 10);
            break;
        }
    }
    fclose(f);
    return kb;
}

/* ---- instances ---- */

/* An initialized Co-Simulation instance of the library `a` (guid `model_guid`), with the given
 * parameters and start values set first. */
static fmi2Component make_of(const Api *a, const char *model_guid, const char *model_resources, const char *name,
                             const fmi2ValueReference *vr, const fmi2Real *value, size_t n, int log_contacts) {
    fmi2Component c =
        a->instantiate(name, fmi2CoSimulation, model_guid, model_resources, &callbacks, fmi2False, fmi2False);
    if (!c) die("fmi2Instantiate failed");
    if (log_contacts) {
        fmi2String categories[] = {"logContactEvents"};
        check(a->set_debug_logging(c, fmi2True, 1, categories), "fmi2SetDebugLogging");
    }
    if (n) check(a->set_real(c, vr, n, value), "fmi2SetReal(parameters)");
    check(a->setup_experiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), "fmi2SetupExperiment");
    check(a->enter_init(c), "fmi2EnterInitializationMode");
    /* A warning is the end of an initialization whose bounds are +inf with the reason logged (with
     * bearing friction, docs/model.md §12). */
    fmi2Status s = a->exit_init(c);
    if (s != fmi2OK && s != fmi2Warning) check(s, "fmi2ExitInitializationMode");
    return c;
}

static void release_of(const Api *a, fmi2Component c) {
    check(a->terminate(c), "fmi2Terminate");
    a->free_instance(c);
}

/* BacklashShaft: the paper's rig (the FMU's start values) unless params are given. */
static fmi2Component make(const char *name, const fmi2ValueReference *vr, const fmi2Real *value, size_t n,
                          int log_contacts) {
    return make_of(&api, guid, resources, name, vr, value, n, log_contacts);
}

static void release(fmi2Component c) { release_of(&api, c); }

/* Gains of the PI loop the bounds assume, the rig's (bench_rig.h): the bounds are then the
 * 5-state closed-loop ones that a user of the loop reads. */
#define KP RIG_Kp
#define KI RIG_Ki
#define DELTA_DEFAULT 0.775e-3 /* the FMU's start value of Delta [rad] */

/* Event-free schedule: pressed into the positive flank near the equilibrium of a constant
 * motor torque (psi ~ tau J_L / (J_m + J_L)), so u stays well past the gap for good. */
#define TAU_PRESS 2.0

/* A Model Exchange instance of the paper's rig in Continuous-Time Mode, in the pressed state of
 * the event-free schedule. */
static fmi2Component make_model_exchange(const char *name) {
    fmi2Component c = api.instantiate(name, fmi2ModelExchange, guid, resources, &callbacks, fmi2False, fmi2False);
    if (!c) die("fmi2Instantiate(fmi2ModelExchange) failed");
    const fmi2ValueReference vr[] = {VR_Kp, VR_Ki, VR_theta_m, VR_tau_m};
    const fmi2Real value[] = {KP, KI, DELTA_DEFAULT + 0.0055, TAU_PRESS};
    check(api.set_real(c, vr, 4, value), "fmi2SetReal(parameters)");
    check(api.setup_experiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), "fmi2SetupExperiment");
    check(api.enter_init(c), "fmi2EnterInitializationMode");
    check(api.exit_init(c), "fmi2ExitInitializationMode");
    fmi2EventInfo info;
    check(api.new_discrete_states(c, &info), "fmi2NewDiscreteStates");
    check(api.enter_continuous_time_mode(c), "fmi2EnterContinuousTimeMode");
    return c;
}

/* The pressed schedule as an FMI 3.0 Co-Simulation instance without early return or Event
 * Mode: fmi3DoStep is then the FMI 2.0 step (docs/model.md §7). */
static fmi3Instance make_pressed3(void) {
    fmi3Instance c = api.instantiate3("fmi3-step", INSTANTIATION_TOKEN, NULL, fmi3False, fmi3False, fmi3False,
                                      fmi3False, NULL, 0, NULL, NULL, NULL);
    if (!c) die("fmi3InstantiateCoSimulation failed");
    const fmi3ValueReference vr[] = {VR_Kp, VR_Ki, VR_theta_m, VR_tau_m};
    const fmi3Float64 value[] = {KP, KI, DELTA_DEFAULT + 0.0055, TAU_PRESS};
    check3(api.set_float64(c, vr, 4, value, 4), "fmi3SetFloat64(parameters)");
    check3(api.enter_init3(c, fmi3False, 0.0, 0.0, fmi3False, 0.0), "fmi3EnterInitializationMode");
    check3(api.exit_init3(c), "fmi3ExitInitializationMode");
    return c;
}
static fmi2Component make_pressed(const char *name, int log_contacts) {
    const fmi2ValueReference vr[] = {VR_Kp, VR_Ki, VR_theta_m};
    const fmi2Real value[] = {KP, KI, DELTA_DEFAULT + 0.0055};
    fmi2Component c = make(name, vr, value, 3, log_contacts);
    const fmi2ValueReference in[] = {VR_tau_m, VR_tau_L};
    const fmi2Real tau[] = {TAU_PRESS, 0.0};
    check(api.set_real(c, in, 2, tau), "fmi2SetReal(inputs)");
    return c;
}

/* The pressed schedule with bearing friction in both bearings (docs/model.md §12): both bodies
 * slide forward from the first step on, with no friction switch (checked like the pressed one),
 * so that the step is the chain's event-free step beside the frictionless one. */
#define TAU_C_SLIDING 0.05
static fmi2Component make_pressed_friction(const char *name, int log_contacts) {
    const fmi2ValueReference vr[] = {VR_Kp, VR_Ki, VR_theta_m, VR_tau_c_m, VR_tau_c_L};
    const fmi2Real value[] = {KP, KI, DELTA_DEFAULT + 0.0055, TAU_C_SLIDING, TAU_C_SLIDING};
    fmi2Component c = make(name, vr, value, 5, log_contacts);
    const fmi2ValueReference in[] = {VR_tau_m, VR_tau_L};
    const fmi2Real tau[] = {TAU_PRESS, 0.0};
    check(api.set_real(c, in, 2, tau), "fmi2SetReal(inputs)");
    return c;
}

/* Switching schedule: the motor swings inside the gap with a speed that alternates between -V
 * and +V at every communication point (held torque +-A with A h = 2 V J_m), so that within each
 * step u reaches past +g or -g by ~V h/4 - g and comes back: a contact made and lost in every
 * step (2 switches), counted by the logger in an untimed run of the same schedule. */
#define V_SWING 6.0
#define J_M 2.28 /* the FMU's start value of J_m [kg.m2], which the swinging instances keep */
static fmi2Component make_swinging(const char *name, int log_contacts) {
    const fmi2ValueReference vr[] = {VR_Kp, VR_Ki, VR_omega_m};
    const fmi2Real value[] = {KP, KI, -V_SWING};
    return make(name, vr, value, 3, log_contacts);
}
static double swing_torque(long k) { return (k % 2 == 0 ? 1.0 : -1.0) * 2.0 * V_SWING * J_M / H; }

/* ---- the other drives: the belt drive, the web line and the two-stage gearbox ----
 *
 * BacklashBelt and BacklashWeb, each dlopened from its own archive, side by side on the schedule
 * of benches/physics.rs `web_benches`: the FMUs' start values (the web line's drive is
 * BacklashBelt's, its span the film line), the belt's default step size, the motor pressed
 * 0.1 mm (in u) past the gap under a constant torque, the web's tension from 5 N with the
 * upstream inputs v_in = T_in = 0. Both with the same speed PI for the bounds (the best-damped
 * gains of the belt drive that `cargo xtask design --model web` finds, rounded), the web also with
 * a tension PI (the gains of `web_bounds_advance_100us`), so that its step advances bound_T too. */
#define H_BELT 1e-4 /* BacklashBelt's and BacklashWeb's default step size [s] */
#define KP_BELT 0.18
#define KI_BELT 57.6
#define KP_T_WEB 0.01
#define KI_T_WEB 0.05
#define TAU_PRESS_BELT 0.5
/* (g + 0.1 mm)/r_m, with BacklashBelt's start values: g = (R_2/R_g1) Delta, r_m = R_1
 * (docs/model.md §1). */
#define THETA_PRESSED_BELT ((0.04 / 0.015 * 5e-5 + 1e-4) / 0.02)

/* BacklashTwoStage (docs/model.md §10) beside the shaft: its start values (bench_vr.h's START_,
 * read from its description), the shaft's h = 1 ms (not its default experiment's step) and the
 * shaft's constant TAU_PRESS and PI gains (KP, KI: those of the shaft's rig, which is also the
 * two-stage rig's in tests/fixtures/rigs.toml), so that its step and its bound's cost compare
 * with the shaft's `ours_step_event_free`. */
#define TS(name) START_BacklashTwoStage_##name

/* One drive's archive: its library, guid and resource URI, and what its schedule sets:
 * parameters and start values before initialization, then the held torques tau_m, tau_L,
 * stepped with step size h. */
#define MAX_START 6
#define MAX_CONTACTS 2
typedef struct {
    Api api;
    const char *guid, *resources;
    fmi2ValueReference start_vr[MAX_START], input_vr[2];
    fmi2Real start[MAX_START];
    size_t n_start;
    fmi2Real tau_m, h;
    /* Each mesh's contact output, read at the end of the untimed check. */
    fmi2ValueReference contact_vr[MAX_CONTACTS];
    size_t n_contact;
    /* The bounds, as a master reading every output reads them after each step. */
    fmi2ValueReference bound_vr[3];
    size_t n_bound;
} Drive;

enum { BELT, WEB, TWO_STAGE, DRIVES };
static Drive drive[DRIVES];

/* The two-stage gearbox pressed into both meshes' positive flanks at the rigid motion that
 * TAU_PRESS gives it from rest: the load accelerating at a, the intermediate shaft at n_2 a, the
 * motor at n_1 n_2 a, each mesh carrying what accelerates the bodies beyond it (J_L ω_L' =
 * n_2 ψ_2, J_i ω_i' = n_1 ψ_1 − ψ_2, docs/model.md §10). Started there, no mesh oscillates; the
 * viscous friction then shifts the meshes' torques slowly as the speed grows, never to zero
 * under a forward torque. theta_L at its start value; theta_i and theta_m past each gap by
 * psi_j / k_j. */
static void two_stage_pressed(fmi2Real *theta_i, fmi2Real *theta_m) {
    double n1 = TS(n_1), n2 = TS(n_2);
    double beyond_1 = TS(J_i) * n2 + TS(J_L) / n2; /* what mesh 1 accelerates, per unit a */
    double a = TAU_PRESS / (TS(J_m) * n1 * n2 + beyond_1 / n1);
    double psi_2 = TS(J_L) * a / n2, psi_1 = beyond_1 * a / n1;
    *theta_i = n2 * TS(theta_L) + TS(Delta_2) + psi_2 / TS(k_2);
    *theta_m = n1 * *theta_i + TS(Delta_1) + psi_1 / TS(k_1);
}

/* Loads the three archives' libraries; the value references are each description's own. */
static void load_drives(char **belt_args, char **web_args, char **two_stage_args) {
    const Drive belt = {
        .start_vr = {VR_BacklashBelt_Kp, VR_BacklashBelt_Ki, VR_BacklashBelt_theta_m},
        .start = {KP_BELT, KI_BELT, THETA_PRESSED_BELT},
        .n_start = 3,
        .input_vr = {VR_BacklashBelt_tau_m, VR_BacklashBelt_tau_L},
        .tau_m = TAU_PRESS_BELT,
        .h = H_BELT,
        .contact_vr = {VR_BacklashBelt_contact},
        .n_contact = 1,
        .bound_vr = {VR_BacklashBelt_bound, VR_BacklashBelt_bound_paper},
        .n_bound = 2,
    };
    const Drive web = {
        .start_vr = {VR_BacklashWeb_Kp, VR_BacklashWeb_Ki, VR_BacklashWeb_theta_m, VR_BacklashWeb_T,
                     VR_BacklashWeb_Kp_T, VR_BacklashWeb_Ki_T},
        .start = {KP_BELT, KI_BELT, THETA_PRESSED_BELT, 5.0, KP_T_WEB, KI_T_WEB},
        .n_start = 6,
        .input_vr = {VR_BacklashWeb_tau_m, VR_BacklashWeb_tau_L},
        .tau_m = TAU_PRESS_BELT,
        .h = H_BELT,
        .contact_vr = {VR_BacklashWeb_contact},
        .n_contact = 1,
        .bound_vr = {VR_BacklashWeb_bound, VR_BacklashWeb_bound_paper, VR_BacklashWeb_bound_T},
        .n_bound = 3,
    };
    fmi2Real theta_i, theta_m;
    two_stage_pressed(&theta_i, &theta_m);
    const Drive two_stage = {
        .start_vr = {VR_BacklashTwoStage_Kp, VR_BacklashTwoStage_Ki, VR_BacklashTwoStage_theta_i,
                     VR_BacklashTwoStage_theta_m},
        .start = {KP, KI, theta_i, theta_m},
        .n_start = 4,
        .input_vr = {VR_BacklashTwoStage_tau_m, VR_BacklashTwoStage_tau_L},
        .tau_m = TAU_PRESS,
        .h = H,
        .contact_vr = {VR_BacklashTwoStage_contact_1, VR_BacklashTwoStage_contact_2},
        .n_contact = 2,
        .bound_vr = {VR_BacklashTwoStage_bound},
        .n_bound = 1,
    };
    drive[BELT] = belt;
    drive[WEB] = web;
    drive[TWO_STAGE] = two_stage;
    char **args[DRIVES] = {belt_args, web_args, two_stage_args};
    for (int i = 0; i < DRIVES; i++) {
        load(&drive[i].api, args[i][0]);
        drive[i].guid = args[i][1];
        drive[i].resources = args[i][2];
    }
}

static fmi2Component make_drive_pressed(const Drive *d, const char *name, int log_contacts) {
    fmi2Component c = make_of(&d->api, d->guid, d->resources, name, d->start_vr, d->start, d->n_start, log_contacts);
    const fmi2Real tau[] = {d->tau_m, 0.0};
    check(d->api.set_real(c, d->input_vr, 2, tau), "fmi2SetReal(inputs)");
    return c;
}

/* ---- floors ---- */

/* A trivial "copy input to output" component with the FMI signatures, called through function
 * pointers exactly as the real library is: the cost of the call pattern itself. */
typedef struct {
    double in[2], out;
} Copy;

static fmi2Status copy_set_real(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Copy *s = c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] > 1) return fmi2Error;
        s->in[vr[i]] = v[i];
    }
    return fmi2OK;
}
static fmi2Status copy_do_step(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_prior) {
    (void)t, (void)h, (void)no_prior;
    Copy *s = c;
    s->out = s->in[0];
    return fmi2OK;
}
static fmi2Status copy_get_real(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Copy *s = c;
    for (size_t i = 0; i < n; i++) v[i] = vr[i] == 0 ? s->out : 0.0;
    return fmi2OK;
}
/* volatile: the compiler must call through the pointers, as with a dlopened library. */
static fmi2SetRealTYPE *volatile copy_set = copy_set_real;
static fmi2DoStepTYPE *volatile copy_step = copy_do_step;
static fmi2GetRealTYPE *volatile copy_get = copy_get_real;

static volatile double sink;

/* ---- modes ---- */

/* The timed blocks of `suite`, reported in this order. */
enum {
    MATVEC,
    COPY,
    SET_GET,
    STEP,
    STEP_FRICTION,
    SET_STEP,
    PATTERN,
    ALL_OUTPUTS,
    SWITCHING,
    DERIVATIVES,
    INDICATORS,
    STATES_DERIVATIVES,
    STEP3,
    BELT_STEP,
    WEB_STEP,
    BELT_FROM_START,
    WEB_FROM_START,
    BELT_READ_BOUNDS,
    WEB_READ_BOUNDS,
    TWO_STAGE_STEP,
    TWO_STAGE_FROM_START,
    TWO_STAGE_READ_BOUNDS,
    BLOCKS
};
static const char *const block_key[BLOCKS] = {
    "matvec_4x4",     "copy_set2_step_get1", "ours_set2_get1",         "ours_step_event_free",
    "ours_step_event_free_friction",
    "ours_set2_step", "ours_set2_step_get1", "ours_set2_step_get_all", "ours_set2_step_switching",
    "me_get_derivatives", "me_get_event_indicators", "me_set_states_get_derivatives", "ours3_step_event_free",
    "belt_step_event_free", "web_step_event_free", "belt_step_from_start", "web_step_from_start",
    "belt_step_read_bounds", "web_step_read_bounds",
    "two_stage_step_event_free", "two_stage_step_from_start", "two_stage_step_read_bounds",
};
/* The rows of the drives (an instance stepped on through the run, and a fresh instance's first
 * steps), and their names in the `@ <name>_pressed_switches` check lines. */
static const int drive_block[DRIVES] = {BELT_STEP, WEB_STEP, TWO_STAGE_STEP};
static const int drive_from_start_block[DRIVES] = {BELT_FROM_START, WEB_FROM_START, TWO_STAGE_FROM_START};
static const int drive_read_bounds_block[DRIVES] = {BELT_READ_BOUNDS, WEB_READ_BOUNDS, TWO_STAGE_READ_BOUNDS};
static const char *const drive_name[DRIVES] = {"belt", "web", "two_stage"};

/* One batch of the floor y = M x, fed back (see `suite`); a function of its own so that its
 * code is the same as in a loop by itself (the matrix in registers). */
__attribute__((noinline)) static void matvec_batch(const double mix_in[16], double x_io[4], long n) {
    double mix[16], x[4], y[4];
    memcpy(mix, mix_in, sizeof mix);
    memcpy(x, x_io, sizeof x);
    for (long k = 0; k < n; k++) {
        for (int i = 0; i < 4; i++)
            y[i] = mix[4 * i] * x[0] + mix[4 * i + 1] * x[1] + mix[4 * i + 2] * x[2] + mix[4 * i + 3] * x[3];
        memcpy(x, y, sizeof x);
    }
    memcpy(x_io, x, sizeof x);
}

/* One batch of the copy component's PI-loop call pattern (see `suite`). */
__attribute__((noinline)) static double copy_batch(Copy *copy, double v, long n) {
    const fmi2ValueReference cin[] = {0, 1}, cout[] = {0};
    for (long k = 0; k < n; k++) {
        double in2[2] = {v, 0.0};
        copy_set(copy, cin, 2, in2);
        copy_step(copy, k * H, H, fmi2True);
        copy_get(copy, cout, 1, &v);
        v = v * 0.999 + 0.001;
    }
    return v;
}

/* Every block is timed once per round, round after round, so that each block's batches are
 * spread over the whole run: a spell of contention on the machine then disturbs a few batches
 * of every block rather than all batches of one. */
static void suite(int batches, long steps) {
    double *t[BLOCKS], *tw[BLOCKS];
    for (int i = 0; i < BLOCKS; i++) {
        t[i] = malloc(sizeof(double) * batches);
        tw[i] = malloc(sizeof(double) * batches);
    }
    const fmi2ValueReference in[] = {VR_tau_m, VR_tau_L};
    const fmi2ValueReference w_m[] = {VR_omega_m};
    const fmi2ValueReference reals[] = {VR_theta_m, VR_omega_m, VR_theta_L, VR_omega_L, VR_psi, VR_bound, VR_bound_paper};
    const fmi2ValueReference contact_vr[] = {VR_contact};
    fmi2Real out[7];
    fmi2Integer contact;
    long total = (long)batches * steps;

    /* Event-free: verify first (untimed, logging on) that the schedule never switches. */
    {
        fmi2Component c = make_pressed("check-pressed", 1);
        contact_messages = 0;
        for (long k = 0; k < total; k++) check(api.do_step(c, k * H, H, fmi2True), "fmi2DoStep");
        check(api.get_integer(c, contact_vr, 1, &contact), "fmi2GetInteger");
        printf("@ pressed_switches %ld %ld\n", contact_messages, total);
        printf("@ pressed_final_contact %d\n", (int)contact);
        release(c);
    }
    /* The same with friction: no contact or friction switch either. */
    {
        fmi2Component c = make_pressed_friction("check-pressed-friction", 1);
        contact_messages = 0;
        for (long k = 0; k < total; k++) check(api.do_step(c, k * H, H, fmi2True), "fmi2DoStep");
        fmi2Integer sliding[2];
        const fmi2ValueReference sliding_vr[] = {VR_sliding_m, VR_sliding_L};
        check(api.get_integer(c, sliding_vr, 2, sliding), "fmi2GetInteger");
        printf("@ pressed_friction_switches %ld %ld %d %d\n", contact_messages, total, (int)sliding[0],
               (int)sliding[1]);
        release(c);
    }
    /* Switching: count the switches of the schedule in an untimed run with logging. */
    {
        fmi2Component c = make_swinging("check-swinging", 1);
        contact_messages = 0;
        for (long k = 0; k < total; k++) {
            double tau[2] = {swing_torque(k), 0.0};
            check(api.set_real(c, in, 2, tau), "fmi2SetReal");
            check(api.do_step(c, k * H, H, fmi2True), "fmi2DoStep");
        }
        printf("@ swinging_switches %ld %ld\n", contact_messages, total);
        release(c);
    }
    /* The other drives' schedules: event-free too, checked the same way; the line ends with
     * each mesh's final contact: "@ <name>_pressed_switches <switches> <steps> <h> <contact>...". */
    for (int i = 0; i < DRIVES; i++) {
        const Drive *d = &drive[i];
        fmi2Component c = make_drive_pressed(d, "check-pressed", 1);
        contact_messages = 0;
        for (long k = 0; k < total; k++) check(d->api.do_step(c, k * d->h, d->h, fmi2True), "fmi2DoStep");
        fmi2Integer contacts[MAX_CONTACTS];
        check(d->api.get_integer(c, d->contact_vr, d->n_contact, contacts), "fmi2GetInteger");
        printf("@ %s_pressed_switches %ld %ld %g", drive_name[i], contact_messages, total, d->h);
        for (size_t j = 0; j < d->n_contact; j++) printf(" %d", (int)contacts[j]);
        printf("\n");
        release_of(&d->api, c);
    }

    /* Floor: y = M x with M orthogonal (two plane rotations; built at run time so nothing
     * folds), fed back so that each product depends on the previous one, as steps do. */
    volatile double angle = 0.7;
    double c1 = cos(angle), s1 = sin(angle), c2 = cos(2 * angle), s2 = sin(2 * angle);
    double m[16] = {c1, -s1, 0, 0, s1, c1, 0, 0, 0, 0, c2, -s2, 0, 0, s2, c2};
    double mix[16], r[16] = {1, 0, 0, 0, 0, c2, 0, -s2, 0, 0, 1, 0, 0, s2, 0, c2};
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            mix[4 * i + j] = 0;
            for (int k = 0; k < 4; k++) mix[4 * i + j] += r[4 * i + k] * m[4 * k + j];
        }
    double x[4] = {0.1, 0.2, 0.3, 0.4};
    /* Floor: the PI loop's call pattern (setReal of 2, doStep, getReal of 1) on the copy
     * component. The floors are ~100x cheaper than a step: longer batches. */
    Copy copy = {{0, 0}, 0};
    double v = 0.5;
    long floor_items = steps * 20;

    fmi2Component step_friction = make_pressed_friction("step-friction", 0);
    long k_step_friction = 0;
    fmi2Component set_get = make_pressed("set-get", 0), step = make_pressed("step", 0),
                  set_step = make_pressed("set-step", 0), pattern = make_pressed("pattern", 0),
                  all = make_pressed("all-outputs", 0), swinging = make_swinging("swinging", 0);
    double tau[2] = {TAU_PRESS, 0.0}, w = 0.0;
    long k_step = 0, k_set_step = 0, k_pattern = 0, k_all = 0, k_swinging = 0;
    fmi2Component me = make_model_exchange("model-exchange");
    fmi3Instance step3 = make_pressed3();
    long k_step3 = 0;
    fmi2Component drive_step[DRIVES];
    for (int i = 0; i < DRIVES; i++) drive_step[i] = make_drive_pressed(&drive[i], drive_name[i], 0);
    long k_drive = 0;
    double dx[4] = {0}, z[VR_EVENT_INDICATORS] = {0}, x_me[4] = {DELTA_DEFAULT + 0.0055, 0.0, 0.0, 0.0};
    double me_sink = 0.0;

    for (int b = 0; b < batches; b++) {
        Tic t0 = tic();
        matvec_batch(mix, x, floor_items);
        toc(t0, floor_items, t[MATVEC], tw[MATVEC], b);

        t0 = tic();
        v = copy_batch(&copy, v, floor_items);
        toc(t0, floor_items, t[COPY], tw[COPY], b);

        t0 = tic();
        for (long i = 0; i < steps; i++) {
            check(api.set_real(set_get, in, 2, tau), "fmi2SetReal");
            check(api.get_real(set_get, w_m, 1, &w), "fmi2GetReal");
        }
        toc(t0, steps, t[SET_GET], tw[SET_GET], b);

        t0 = tic();
        for (long i = 0; i < steps; i++, k_step++) check(api.do_step(step, k_step * H, H, fmi2True), "fmi2DoStep");
        toc(t0, steps, t[STEP], tw[STEP], b);

        /* The event-free step with friction, right after the frictionless one. */
        t0 = tic();
        for (long i = 0; i < steps; i++, k_step_friction++)
            check(api.do_step(step_friction, k_step_friction * H, H, fmi2True), "fmi2DoStep");
        toc(t0, steps, t[STEP_FRICTION], tw[STEP_FRICTION], b);

        t0 = tic();
        for (long i = 0; i < steps; i++, k_set_step++) {
            check(api.set_real(set_step, in, 2, tau), "fmi2SetReal");
            check(api.do_step(set_step, k_set_step * H, H, fmi2True), "fmi2DoStep");
        }
        toc(t0, steps, t[SET_STEP], tw[SET_STEP], b);

        t0 = tic();
        for (long i = 0; i < steps; i++, k_pattern++) {
            check(api.set_real(pattern, in, 2, tau), "fmi2SetReal");
            check(api.do_step(pattern, k_pattern * H, H, fmi2True), "fmi2DoStep");
            check(api.get_real(pattern, w_m, 1, &w), "fmi2GetReal");
        }
        toc(t0, steps, t[PATTERN], tw[PATTERN], b);

        t0 = tic();
        for (long i = 0; i < steps; i++, k_all++) {
            check(api.set_real(all, in, 2, tau), "fmi2SetReal");
            check(api.do_step(all, k_all * H, H, fmi2True), "fmi2DoStep");
            check(api.get_real(all, reals, 7, out), "fmi2GetReal");
            check(api.get_integer(all, contact_vr, 1, &contact), "fmi2GetInteger");
        }
        toc(t0, steps, t[ALL_OUTPUTS], tw[ALL_OUTPUTS], b);

        t0 = tic();
        for (long i = 0; i < steps; i++, k_swinging++) {
            double swing[2] = {swing_torque(k_swinging), 0.0};
            check(api.set_real(swinging, in, 2, swing), "fmi2SetReal");
            check(api.do_step(swinging, k_swinging * H, H, fmi2True), "fmi2DoStep");
        }
        toc(t0, steps, t[SWITCHING], tw[SWITCHING], b);

        /* Model Exchange: the calls a solver makes per right-hand side evaluation. The results
         * feed a sum, so that no call can be dropped; the state moves a little each time. */
        t0 = tic();
        for (long i = 0; i < floor_items; i++) {
            check(api.get_derivatives(me, dx, 4), "fmi2GetDerivatives");
            me_sink += dx[1];
        }
        toc(t0, floor_items, t[DERIVATIVES], tw[DERIVATIVES], b);

        t0 = tic();
        for (long i = 0; i < floor_items; i++) {
            check(api.get_event_indicators(me, z, VR_EVENT_INDICATORS), "fmi2GetEventIndicators");
            me_sink += z[0];
        }
        toc(t0, floor_items, t[INDICATORS], tw[INDICATORS], b);

        t0 = tic();
        for (long i = 0; i < floor_items; i++) {
            x_me[1] = 1e-9 * (double)(i & 1023);
            check(api.set_continuous_states(me, x_me, 4), "fmi2SetContinuousStates");
            check(api.get_derivatives(me, dx, 4), "fmi2GetDerivatives");
            me_sink += dx[1];
        }
        toc(t0, floor_items, t[STATES_DERIVATIVES], tw[STATES_DERIVATIVES], b);

        /* The FMI 3.0 event-free step, beside the FMI 2.0 one (STEP) in the same round. */
        t0 = tic();
        for (long i = 0; i < steps; i++, k_step3++) {
            fmi3Boolean event, terminate, early;
            fmi3Float64 last;
            check3(api.do_step3(step3, k_step3 * H, H, fmi3True, &event, &terminate, &early, &last), "fmi3DoStep");
        }
        toc(t0, steps, t[STEP3], tw[STEP3], b);

        /* The other drives' event-free steps, one batch each, in turns: which goes first
         * rotates from round to round. All take the same steps, k_drive on (each at its own h);
         * then the same number of steps from t = 0 on a fresh instance (made and freed untimed),
         * since a step costs more while the bounds' responses are still being integrated. */
        for (int j = 0; j < DRIVES; j++) {
            int i = (b + j) % DRIVES;
            const Drive *d = &drive[i];
            long k = k_drive;
            t0 = tic();
            for (long n = 0; n < steps; n++, k++)
                check(d->api.do_step(drive_step[i], k * d->h, d->h, fmi2True), "fmi2DoStep");
            toc(t0, steps, t[drive_block[i]], tw[drive_block[i]], b);
        }
        k_drive += steps;
        for (int j = 0; j < DRIVES; j++) {
            int i = (b + j) % DRIVES;
            const Drive *d = &drive[i];
            fmi2Component fresh = make_drive_pressed(d, drive_name[i], 0);
            t0 = tic();
            for (long k = 0; k < steps; k++) check(d->api.do_step(fresh, k * d->h, d->h, fmi2True), "fmi2DoStep");
            toc(t0, steps, t[drive_from_start_block[i]], tw[drive_from_start_block[i]], b);
            release_of(&d->api, fresh);
        }
        /* The same first steps with the bounds read after each: their cost, brought up to the
         * step when read (docs/model.md §3). */
        for (int j = 0; j < DRIVES; j++) {
            int i = (b + j) % DRIVES;
            const Drive *d = &drive[i];
            fmi2Component fresh = make_drive_pressed(d, drive_name[i], 0);
            fmi2Real bounds[3];
            t0 = tic();
            for (long k = 0; k < steps; k++) {
                check(d->api.do_step(fresh, k * d->h, d->h, fmi2True), "fmi2DoStep");
                check(d->api.get_real(fresh, d->bound_vr, d->n_bound, bounds), "fmi2GetReal(bounds)");
            }
            toc(t0, steps, t[drive_read_bounds_block[i]], tw[drive_read_bounds_block[i]], b);
            sink = bounds[0];
            release_of(&d->api, fresh);
        }
    }
    for (int i = 0; i < DRIVES; i++) release_of(&drive[i].api, drive_step[i]);
    api.free_instance3(step3);
    /* In contact at the pressed state: der(omega_m) = (tau - r psi)/J_m, independent of the host. */
    printf("@ me_pressed_derivatives %.17g %.17g %.17g %.17g %.6g\n", dx[0], dx[1], dx[2], dx[3], me_sink);
    api.free_instance(me);
    sink = x[0] + x[1] + x[2] + x[3] + v + w + out[5] + out[6] + contact;
    printf("@ all_outputs_final_bound %.17g %.17g\n", out[5], out[6]);
    for (int i = 0; i < BLOCKS; i++) {
        report(block_key[i], t[i], tw[i], batches);
        free(t[i]);
        free(tw[i]);
    }
    fmi2Component made[] = {set_get, step, set_step, pattern, all, swinging};
    for (size_t i = 0; i < sizeof made / sizeof made[0]; i++) release(made[i]);
}

static void scale(long steps) {
    long rss_before = status_kb("VmRSS");
    fmi2Component c = make_pressed("scale", 0);
    Tic t0 = tic();
    for (long k = 0; k < steps; k++) check(api.do_step(c, k * H, H, fmi2True), "fmi2DoStep");
    Tic t1 = tic();
    double elapsed = t1.wall - t0.wall, cpu = t1.cpu - t0.cpu;
    const fmi2ValueReference contact_vr[] = {VR_contact};
    fmi2Integer contact;
    check(api.get_integer(c, contact_vr, 1, &contact), "fmi2GetInteger");
    printf("@ scale %ld %.6g %.6g %ld %ld %ld %d %.6g\n", steps, elapsed / 1e9, cpu / steps, rss_before,
           status_kb("VmRSS"), status_kb("VmHWM"), (int)contact, elapsed / steps);
    release(c);
}

static void instances(int count, int batches, long per_batch) {
    fmi2Component *c = malloc(sizeof *c * count);
    double *t = malloc(sizeof(double) * batches), *tw = malloc(sizeof(double) * batches);
    long rss_before = status_kb("VmRSS");
    Tic t0 = tic();
    for (int i = 0; i < count; i++) {
        char name[32];
        snprintf(name, sizeof name, "instance-%d", i);
        c[i] = make_pressed(name, 0);
    }
    double setup_ns = (tic().cpu - t0.cpu) / count;
    long rss_after = status_kb("VmRSS");
    long rounds = per_batch / count > 0 ? per_batch / count : 1;
    long k = 0;
    for (int b = 0; b < batches; b++) {
        Tic s0 = tic();
        for (long r = 0; r < rounds; r++, k++)
            for (int i = 0; i < count; i++) check(api.do_step(c[i], k * H, H, fmi2True), "fmi2DoStep");
        toc(s0, (double)rounds * count, t, tw, b);
    }
    qsort(t, batches, sizeof(double), cmp_double);
    qsort(tw, batches, sizeof(double), cmp_double);
    printf("@ instances %d %.6g %.6g %.6g %.6g %ld %ld %ld %.6g\n", count, quantile(t, batches, 0.5),
           quantile(t, batches, 0.25), quantile(t, batches, 0.75), setup_ns, rss_before, rss_after,
           status_kb("VmHWM"), quantile(tw, batches, 0.5));
    for (int i = 0; i < count; i++) release(c[i]);
    free(c);
    free(t);
    free(tw);
}

/* The closed loop of benches/python_bench.py, here in C: the sampled PI of
 * tests/python/reference.py (SampledPI) on omega_m, reference 5 sin(2 pi 0.5 t) rad/s, load
 * torque -2 N.m from t = 4 s, on BacklashShaft's rig (bench_rig.h; the Python bench's
 * tests/python/rigs.py SHAFT, SHAFT_GAINS, from the same fixture). */
static void piloop(double seconds, int repeats) {
    const fmi2ValueReference pv[] = RIG_VR;
    const fmi2Real pval[] = RIG_VALUE;
    _Static_assert(sizeof pv / sizeof pv[0] == sizeof pval / sizeof pval[0], "RIG_VR and RIG_VALUE differ in length");
    const fmi2ValueReference in[] = {VR_tau_m, VR_tau_L}, w_m[] = {VR_omega_m};
    const fmi2ValueReference state[] = {VR_theta_m, VR_omega_m, VR_theta_L, VR_omega_L};
    long n = (long)llround(seconds / H);
    double *t = malloc(sizeof(double) * repeats), *tw = malloc(sizeof(double) * repeats), z[4];
    for (int r = 0; r < repeats; r++) {
        fmi2Component c = make("piloop", pv, pval, sizeof pv / sizeof pv[0], 0);
        double x = 0.0, w = 0.0;
        Tic t0 = tic();
        for (long k = 0; k < n; k++) {
            double tk = k * H;
            check(api.get_real(c, w_m, 1, &w), "fmi2GetReal");
            double e = 5.0 * sin(2 * M_PI * 0.5 * tk) - w;
            double tau[2] = {KP * e + KI * x, tk >= 4.0 ? -2.0 : 0.0};
            x += H * e;
            check(api.set_real(c, in, 2, tau), "fmi2SetReal");
            check(api.do_step(c, tk, H, fmi2True), "fmi2DoStep");
        }
        toc(t0, n, t, tw, r);
        check(api.get_real(c, state, 4, z), "fmi2GetReal");
        release(c);
    }
    report("piloop_step", t, tw, repeats);
    printf("@ piloop_final %.17g %.17g %.17g %.17g %ld\n", z[0], z[1], z[2], z[3], n);
    free(t);
    free(tw);
}

int main(int argc, char **argv) {
    if (argc < 5)
        die("usage: native_host <lib.so> <guid> <resource-uri> suite|scale|instances|piloop [args] (see the top "
            "of native_host.c)");
    load(&api, argv[1]);
    guid = argv[2];
    resources = argv[3];
    const char *mode = argv[4];
    if (strcmp(mode, "suite") == 0 && argc == 16) {
        load_drives(&argv[7], &argv[10], &argv[13]);
        suite(atoi(argv[5]), atol(argv[6]));
    } else if (strcmp(mode, "scale") == 0 && argc == 6) {
        scale(atol(argv[5]));
    } else if (strcmp(mode, "instances") == 0 && argc == 8) {
        instances(atoi(argv[5]), atoi(argv[6]), atol(argv[7]));
    } else if (strcmp(mode, "piloop") == 0 && argc == 7) {
        piloop(atof(argv[5]), atoi(argv[6]));
    } else {
        die("unknown mode or wrong argument count: %s", mode);
    }
    return 0;
}
