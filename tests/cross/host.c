/* FMI 2.0 and FMI 3.0 Co-Simulation host of the cross-platform test (xtask/src/cross/): the same
 * program is compiled for every platform the FMU ships (cc for linux64, x86_64-w64-mingw32-gcc for
 * win64 under Wine, aarch64-linux-gnu-gcc under qemu), loads one platform's library and prints
 * what it observed, one result per line:
 *
 *     @ sample <k> <contacts> <switches> <bits of each output given>
 *     @ early <k> <contacts> <switches> <bits of lastSuccessfulTime> <bits of the same outputs>
 *     @ misuse <case> <status> <messages logged>
 *     @ saved <size in bytes>
 *
 * Reals are printed as the hexadecimal IEEE-754 bits, so that the comparison of two platforms in
 * xtask sees every bit. The host computes its inputs with +, - and * only (no libm, no fused
 * multiply-add: built with -ffp-contract=off), so every platform feeds the FMU identical inputs.
 *
 * usage: host <library> <token> <variables> <parameters> <scenario> [args]
 *   <token>       the guid of the FMI 2.0 description, or for the fmi3 scenario the
 *                 instantiationToken of the FMI 3.0 one
 *   <variables>   name=vr,... for tau_m tau_L omega_m Kp Ki (read by xtask from the archive's
 *                 modelDescription.xml), and for a web line (BacklashWeb) also v_in T_in: the
 *                 host then sets the upstream web speed and tension as inputs too; then
 *                 out=vr for each Real output a sample prints, in their order, and contact=vr
 *                 for each mesh's Integer contact mode (<contacts>: their values joined by
 *                 commas; <switches>: the changes of any of them, each mesh's counted)
 *   <parameters>  vr=bits,... Real parameters set before initialization, each value as the
 *                 hexadecimal IEEE-754 bits (no platform's decimal conversion enters the run);
 *                 must include Kp and Ki, which are also the gains of the host's PI loop
 *   closed <steps> <every>           PI loop on omega_m, square-wave reference, load step
 *   open <steps> <every>             square-wave motor torque, no controller
 *   save <steps> <every> <file>      open loop: fmi2SerializeFMUstate at steps/2 into <file>,
 *                                    then the samples of the rest of the run
 *   restore <steps> <every> <file>   a fresh instance restores <file> and runs the rest
 *   misuse                           calls FMI 2.0 forbids, and the status each gets; then the
 *                                    library closed and reopened under a live instance
 *   fmi3 <steps> <every>             the open loop through FMI 3.0 (fmi3DoStep with early return
 *                                    allowed): each step stops at every contact switch inside it
 *                                    (an `early` line) and continues from there to its end
 *   controller <steps> <every> <guid> <omega_m vr>,<tau_m vr> <parameters>
 *                                    the loop closed by BacklashController, an instance of the
 *                                    same library (its guid, the value references of its input
 *                                    omega_m and output tau_m, its Real parameters as vr=bits,...):
 *                                    values passed after each step, as a co-simulation master does
 */
#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
#else
#include <dlfcn.h>
#endif

#include "fmi2Functions.h"
#include "fmi3Functions.h"

#define H 1e-3 /* communication step [s] */

static void die(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "cross host: ");
    vfprintf(stderr, fmt, ap);
    fprintf(stderr, "\n");
    va_end(ap);
    exit(1);
}

/* ---- the library: LoadLibrary/GetProcAddress on Windows, dlopen/dlsym elsewhere ---- */

static void *library;
static const char *library_path;

static void open_library(const char *path) {
    library_path = path;
#ifdef _WIN32
    library = (void *)LoadLibraryA(path);
    if (!library) die("LoadLibrary %s failed (error %lu)", path, (unsigned long)GetLastError());
#else
    library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!library) die("dlopen %s: %s", path, dlerror());
#endif
}

/* Closes the library as an importer does that unloads it (its last reference: the host holds one). */
static void close_library(void) {
#ifdef _WIN32
    if (!FreeLibrary((HMODULE)library)) die("FreeLibrary failed (error %lu)", (unsigned long)GetLastError());
#else
    if (dlclose(library) != 0) die("dlclose: %s", dlerror());
#endif
    library = NULL;
}

static void *symbol(const char *name) {
#ifdef _WIN32
    void *f = (void *)GetProcAddress((HMODULE)library, name);
#else
    void *f = dlsym(library, name);
#endif
    if (!f) die("%s is not exported", name);
    return f;
}

static struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetupExperimentTYPE *setup_experiment;
    fmi2EnterInitializationModeTYPE *enter_init;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2TerminateTYPE *terminate;
    fmi2SetRealTYPE *set_real;
    fmi2GetRealTYPE *get_real;
    fmi2GetIntegerTYPE *get_integer;
    fmi2DoStepTYPE *do_step;
    fmi2GetFMUstateTYPE *get_state;
    fmi2SetFMUstateTYPE *set_state;
    fmi2FreeFMUstateTYPE *free_state;
    fmi2SerializedFMUstateSizeTYPE *serialized_size;
    fmi2SerializeFMUstateTYPE *serialize;
    fmi2DeSerializeFMUstateTYPE *deserialize;
} api;

static struct {
    fmi3InstantiateCoSimulationTYPE *instantiate;
    fmi3FreeInstanceTYPE *free_instance;
    fmi3EnterInitializationModeTYPE *enter_init;
    fmi3ExitInitializationModeTYPE *exit_init;
    fmi3TerminateTYPE *terminate;
    fmi3SetFloat64TYPE *set_float64;
    fmi3GetFloat64TYPE *get_float64;
    fmi3GetInt32TYPE *get_int32;
    fmi3DoStepTYPE *do_step;
} api3;

static void load(const char *path) {
    open_library(path);
    api.instantiate = (fmi2InstantiateTYPE *)symbol("fmi2Instantiate");
    api.free_instance = (fmi2FreeInstanceTYPE *)symbol("fmi2FreeInstance");
    api.setup_experiment = (fmi2SetupExperimentTYPE *)symbol("fmi2SetupExperiment");
    api.enter_init = (fmi2EnterInitializationModeTYPE *)symbol("fmi2EnterInitializationMode");
    api.exit_init = (fmi2ExitInitializationModeTYPE *)symbol("fmi2ExitInitializationMode");
    api.terminate = (fmi2TerminateTYPE *)symbol("fmi2Terminate");
    api.set_real = (fmi2SetRealTYPE *)symbol("fmi2SetReal");
    api.get_real = (fmi2GetRealTYPE *)symbol("fmi2GetReal");
    api.get_integer = (fmi2GetIntegerTYPE *)symbol("fmi2GetInteger");
    api.do_step = (fmi2DoStepTYPE *)symbol("fmi2DoStep");
    api.get_state = (fmi2GetFMUstateTYPE *)symbol("fmi2GetFMUstate");
    api.set_state = (fmi2SetFMUstateTYPE *)symbol("fmi2SetFMUstate");
    api.free_state = (fmi2FreeFMUstateTYPE *)symbol("fmi2FreeFMUstate");
    api.serialized_size = (fmi2SerializedFMUstateSizeTYPE *)symbol("fmi2SerializedFMUstateSize");
    api.serialize = (fmi2SerializeFMUstateTYPE *)symbol("fmi2SerializeFMUstate");
    api.deserialize = (fmi2DeSerializeFMUstateTYPE *)symbol("fmi2DeSerializeFMUstate");
    api3.instantiate = (fmi3InstantiateCoSimulationTYPE *)symbol("fmi3InstantiateCoSimulation");
    api3.free_instance = (fmi3FreeInstanceTYPE *)symbol("fmi3FreeInstance");
    api3.enter_init = (fmi3EnterInitializationModeTYPE *)symbol("fmi3EnterInitializationMode");
    api3.exit_init = (fmi3ExitInitializationModeTYPE *)symbol("fmi3ExitInitializationMode");
    api3.terminate = (fmi3TerminateTYPE *)symbol("fmi3Terminate");
    api3.set_float64 = (fmi3SetFloat64TYPE *)symbol("fmi3SetFloat64");
    api3.get_float64 = (fmi3GetFloat64TYPE *)symbol("fmi3GetFloat64");
    api3.get_int32 = (fmi3GetInt32TYPE *)symbol("fmi3GetInt32");
    api3.do_step = (fmi3DoStepTYPE *)symbol("fmi3DoStep");
}

/* ---- value references, by name ---- */

/* The variables the host drives, then the web line's inputs (from V_IN on): given both or none. */
enum { TAU_M, TAU_L, OMEGA_M, KP, KI, V_IN, T_IN, NVARS };
static const char *const var_name[NVARS] = {"tau_m", "tau_L", "omega_m", "Kp", "Ki", "v_in", "T_in"};
static fmi2ValueReference vr[NVARS];

/* The model is a web line: its variables from V_IN on were given. */
static int web;

/* What a sample prints: the Real outputs (out=vr, in their order) and the contact modes
 * (contact=vr, one per mesh). */
#define MAX_OUTPUTS 16
#define MAX_CONTACTS 4
static fmi2ValueReference out_vr[MAX_OUTPUTS], contact_vr[MAX_CONTACTS];
static size_t n_out, n_contacts;

static fmi2ValueReference value_reference(const char *name, const char *text, const char *end) {
    char *stop;
    unsigned long value = strtoul(text, &stop, 10);
    if (stop == text || stop != end) die("variables: value reference of %s is not a number", name);
    return (fmi2ValueReference)value;
}

/* Parses "name=vr,name=vr,..."; every name of var_name before V_IN must be given, the web line's
 * both or none, and at least one out and one contact. */
static void parse_variables(const char *list) {
    int seen[NVARS] = {0};
    const char *p = list;
    while (*p) {
        const char *eq = strchr(p, '='), *end = strchr(p, ',');
        if (!end) end = p + strlen(p);
        if (!eq || eq > end) die("variables: expected name=vr in `%s`", p);
        const size_t length = (size_t)(eq - p);
        int known = 0;
        if (length == 3 && strncmp(p, "out", 3) == 0) {
            if (n_out == MAX_OUTPUTS) die("variables: more than %d outputs", MAX_OUTPUTS);
            out_vr[n_out++] = value_reference("out", eq + 1, end), known = 1;
        } else if (length == 7 && strncmp(p, "contact", 7) == 0) {
            if (n_contacts == MAX_CONTACTS) die("variables: more than %d contacts", MAX_CONTACTS);
            contact_vr[n_contacts++] = value_reference("contact", eq + 1, end), known = 1;
        }
        for (int i = 0; i < NVARS; i++) {
            if (length == strlen(var_name[i]) && strncmp(p, var_name[i], length) == 0) {
                vr[i] = value_reference(var_name[i], eq + 1, end);
                seen[i] = known = 1;
            }
        }
        if (!known) die("variables: unknown name in `%s`", p);
        p = *end ? end + 1 : end;
    }
    for (int i = 0; i < V_IN; i++)
        if (!seen[i]) die("variables: no value reference for %s", var_name[i]);
    int web_seen = 0;
    for (int i = V_IN; i < NVARS; i++) web_seen += seen[i];
    if (web_seen != 0 && web_seen != NVARS - V_IN) die("variables: some of the web line's, not all");
    web = web_seen != 0;
    if (n_out == 0 || n_contacts == 0) die("variables: no out= or no contact= given");
}

/* Parameters: value references and values, parsed from "vr=bits,..."; kp, ki among them. */
#define MAX_PARAMETERS 32
static fmi2ValueReference param_vr[MAX_PARAMETERS];
static fmi2Real param_value[MAX_PARAMETERS];
static size_t n_params;
static double kp, ki;

/* Parses "vr=bits,..." (each value as its hexadecimal IEEE-754 bits) into refs and values;
 * returns how many. */
static size_t parse_bits(const char *list, fmi2ValueReference refs[MAX_PARAMETERS], fmi2Real values[MAX_PARAMETERS]) {
    size_t n = 0;
    for (const char *p = list; *p;) {
        if (n == MAX_PARAMETERS) die("parameters: more than %d", MAX_PARAMETERS);
        char *eq, *end;
        unsigned long ref = strtoul(p, &eq, 10);
        if (eq == p || *eq != '=') die("parameters: expected vr=bits in `%s`", p);
        uint64_t bits = (uint64_t)strtoull(eq + 1, &end, 16);
        if (end == eq + 1 || (*end && *end != ',')) die("parameters: expected hexadecimal bits in `%s`", p);
        refs[n] = (fmi2ValueReference)ref;
        memcpy(&values[n++], &bits, sizeof bits);
        p = *end ? end + 1 : end;
    }
    return n;
}

static void parse_parameters(const char *list) {
    int have_kp = 0, have_ki = 0;
    n_params = parse_bits(list, param_vr, param_value);
    for (size_t i = 0; i < n_params; i++) {
        if (param_vr[i] == vr[KP]) kp = param_value[i], have_kp = 1;
        if (param_vr[i] == vr[KI]) ki = param_value[i], have_ki = 1;
    }
    if (!have_kp || !have_ki) die("parameters: Kp and Ki must be given");
}

/* ---- logger: counts messages; shows them only when CROSS_HOST_VERBOSE is set ---- */

static long messages;
static int verbose;

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env;
    messages++;
    if (!verbose) return;
    va_list ap;
    va_start(ap, message);
    fprintf(stderr, "[%s] %s (status %d): ", instance ? instance : "?", category ? category : "?", (int)status);
    vfprintf(stderr, message, ap);
    fprintf(stderr, "\n");
    va_end(ap);
}

static const fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};

static void logger3(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
    messages++;
    if (verbose) fprintf(stderr, "%s (status %d): %s\n", category ? category : "?", (int)status, message ? message : "");
}

/* The guid (FMI 2.0) or the instantiationToken (FMI 3.0) of the description. */
static const char *token;

/* An fmi2Status or fmi3Status: OK is 0 in both. */
static void check(int s, const char *what) {
    if (s != 0) die("%s returned status %d", what, s);
}

/* The end of initialization: OK, or a warning (fmi2Warning, fmi3Warning: 1) where a bound is +inf
 * with its reason logged, as with bearing friction (docs/model.md §12). */
static void check_initialized(int s, const char *what) {
    if (s != 0 && s != 1) die("%s returned status %d", what, s);
}

/* An initialized instance with the given parameters. */
static fmi2Component make(const char *name) {
    fmi2Component c = api.instantiate(name, fmi2CoSimulation, token, "", &callbacks, fmi2False, fmi2False);
    if (!c) die("fmi2Instantiate(%s) returned NULL", name);
    check(api.set_real(c, param_vr, n_params, param_value), "fmi2SetReal(parameters)");
    check(api.setup_experiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), "fmi2SetupExperiment");
    check(api.enter_init(c), "fmi2EnterInitializationMode");
    check_initialized(api.exit_init(c), "fmi2ExitInitializationMode");
    return c;
}

static void release(fmi2Component c) {
    check(api.terminate(c), "fmi2Terminate");
    api.free_instance(c);
}

/* An initialized FMI 3.0 Co-Simulation instance with the given parameters, whose fmi3DoStep
 * returns early at contact switches (earlyReturnAllowed, without Event Mode). */
static fmi3Instance make3(const char *name) {
    fmi3Instance c = api3.instantiate(name, token, NULL, fmi3False, fmi3False, fmi3False, fmi3True, NULL, 0, NULL,
                                      logger3, NULL);
    if (!c) die("fmi3InstantiateCoSimulation(%s) returned NULL", name);
    fmi3ValueReference refs[MAX_PARAMETERS];
    for (size_t i = 0; i < n_params; i++) refs[i] = param_vr[i];
    check(api3.set_float64(c, refs, n_params, param_value, n_params), "fmi3SetFloat64(parameters)");
    check(api3.enter_init(c, fmi3False, 0.0, 0.0, fmi3False, 0.0), "fmi3EnterInitializationMode");
    check_initialized(api3.exit_init(c), "fmi3ExitInitializationMode");
    return c;
}

/* ---- what is compared: every output at sample points, and the contact switches ---- */

static uint64_t bits(double x) {
    uint64_t b;
    memcpy(&b, &x, sizeof b);
    return b;
}

static fmi2Integer last_contact[MAX_CONTACTS];
static long switches;

/* Each mesh whose contact mode changed is one switch. */
static void note_contacts(const fmi2Integer contact[MAX_CONTACTS]) {
    for (size_t i = 0; i < n_contacts; i++) {
        if (contact[i] != last_contact[i]) switches++;
        last_contact[i] = contact[i];
    }
}

static void read_contacts(fmi2Component c, fmi2Integer contact[MAX_CONTACTS]) {
    check(api.get_integer(c, contact_vr, n_contacts, contact), "fmi2GetInteger(contact)");
}

static void count_switch(fmi2Component c) {
    fmi2Integer contact[MAX_CONTACTS];
    read_contacts(c, contact);
    note_contacts(contact);
}

static void count_switch3(fmi3Instance c) {
    fmi3ValueReference refs[MAX_CONTACTS];
    fmi3Int32 contact3[MAX_CONTACTS];
    fmi2Integer contact[MAX_CONTACTS];
    for (size_t i = 0; i < n_contacts; i++) refs[i] = contact_vr[i];
    check(api3.get_int32(c, refs, n_contacts, contact3, n_contacts), "fmi3GetInt32(contact)");
    for (size_t i = 0; i < n_contacts; i++) contact[i] = contact3[i];
    note_contacts(contact);
}

/* "@ <kind> <k> <contacts> <switches>" of a sample line. */
static void print_head(const char *kind, long k) {
    printf("@ %s %ld ", kind, k);
    for (size_t i = 0; i < n_contacts; i++) printf(i ? ",%d" : "%d", (int)last_contact[i]);
    printf(" %ld", switches);
}

static void print_outputs(const double out[MAX_OUTPUTS]) {
    for (size_t i = 0; i < n_out; i++) printf(" %016" PRIx64, bits(out[i]));
    printf("\n");
}

static void sample(fmi2Component c, long k) {
    fmi2Real out[MAX_OUTPUTS];
    check(api.get_real(c, out_vr, n_out, out), "fmi2GetReal(outputs)");
    print_head("sample", k);
    print_outputs(out);
}

/* The outputs through FMI 3.0: after step k, or (`early` not NULL) at the instant *early inside
 * step k where fmi3DoStep returned early. */
static void sample3(fmi3Instance c, long k, const fmi3Float64 *early) {
    fmi3ValueReference refs[MAX_OUTPUTS];
    fmi3Float64 out[MAX_OUTPUTS];
    for (size_t i = 0; i < n_out; i++) refs[i] = out_vr[i];
    check(api3.get_float64(c, refs, n_out, out, n_out), "fmi3GetFloat64(outputs)");
    if (early) {
        print_head("early", k);
        printf(" %016" PRIx64, bits(*early));
    } else {
        print_head("sample", k);
    }
    print_outputs(out);
}

/* ---- scenarios ---- */

/* Square wave of amplitude a and period 2 half_period steps: the sign flips every half_period. */
static double square(long k, long half_period, double a) { return (k / half_period) % 2 == 0 ? a : -a; }

/* Open loop: the motor torque reverses every 0.4 s, so the motor crosses the gap and takes up
 * the other flank again and again (contact made and lost); a load torque from t = 1 s. The
 * torques tau_m, tau_L of step k. */
static void open_torques(long k, double tau[2]) {
    tau[0] = square(k, 400, 3.0);
    tau[1] = k >= 1000 ? -0.5 : 0.0;
}

/* A web line's upstream web speed v_in [m/s] and tension T_in [N] in step k: the web enters a
 * little slower or faster by turns, under a tension that steps up at t = 2 s. */
static void web_upstream(long k, double *v_in, double *t_in) {
    *v_in = 0.02 + square(k, 300, 0.01);
    *t_in = k >= 2000 ? 60.0 : 40.0;
}

/* The inputs of step k: the torques `tau`, and on a web line also its upstream speed and tension.
 * Fills ref and value; returns how many. */
#define MAX_INPUTS 4
static size_t step_inputs(long k, const double tau[2], fmi2ValueReference ref[MAX_INPUTS], double value[MAX_INPUTS]) {
    ref[0] = vr[TAU_M], value[0] = tau[0];
    ref[1] = vr[TAU_L], value[1] = tau[1];
    if (!web) return 2;
    ref[2] = vr[V_IN], ref[3] = vr[T_IN];
    web_upstream(k, &value[2], &value[3]);
    return 4;
}

static void set_inputs(fmi2Component c, long k, const double tau[2]) {
    fmi2ValueReference ref[MAX_INPUTS];
    fmi2Real value[MAX_INPUTS];
    size_t n = step_inputs(k, tau, ref, value);
    check(api.set_real(c, ref, n, value), "fmi2SetReal(inputs)");
}

static void open_inputs(fmi2Component c, long k) {
    fmi2Real tau[2];
    open_torques(k, tau);
    set_inputs(c, k, tau);
}

static void run_open(fmi2Component c, long from, long to, long every) {
    for (long k = from; k < to; k++) {
        open_inputs(c, k);
        check(api.do_step(c, k * H, H, fmi2True), "fmi2DoStep");
        count_switch(c);
        if ((k + 1) % every == 0) sample(c, k + 1);
    }
}

static void open_loop(long steps, long every) {
    fmi2Component c = make("open");
    run_open(c, 0, steps, every);
    release(c);
}

/* The open loop through FMI 3.0: the inputs of step k set once, then fmi3DoStep from where the
 * FMU stopped to the end of the step, again after every early return at a contact switch. */
static void fmi3_open_loop(long steps, long every) {
    fmi3Instance c = make3("fmi3");
    for (long k = 0; k < steps; k++) {
        double tau[2], value[MAX_INPUTS];
        fmi2ValueReference ref[MAX_INPUTS];
        fmi3ValueReference ref3[MAX_INPUTS];
        open_torques(k, tau);
        size_t n = step_inputs(k, tau, ref, value);
        for (size_t i = 0; i < n; i++) ref3[i] = ref[i];
        check(api3.set_float64(c, ref3, n, value, n), "fmi3SetFloat64(inputs)");
        /* The first call takes the whole step, as fmi2DoStep does in the open loop. */
        const double end = k * H + H;
        double t = k * H, h = H;
        for (;;) {
            fmi3Boolean event = fmi3False, terminate = fmi3False, early = fmi3False;
            fmi3Float64 last = t;
            check(api3.do_step(c, t, h, fmi3True, &event, &terminate, &early, &last), "fmi3DoStep");
            if (event || terminate) die("fmi3DoStep at t = %.17g asked for Event Mode or termination", t);
            count_switch3(c);
            if (!early) break;
            /* Each return must move time, or the step would never end. */
            if (!(last > t && last < end)) die("fmi3DoStep from t = %.17g returned early at %.17g", t, last);
            sample3(c, k + 1, &last);
            t = last;
            h = end - t;
        }
        if ((k + 1) % every == 0) sample3(c, k + 1, NULL);
    }
    check(api3.terminate(c), "fmi3Terminate");
    api3.free_instance(c);
}

/* Closed loop: a sampled PI on the motor speed (the FMU's Kp, Ki) tracks a reference that
 * reverses between +5 and -5 rad/s every second; a load torque of -2 N.m from t = 4 s. */
static void closed_loop(long steps, long every) {
    fmi2Component c = make("closed");
    double integral = 0.0, w = 0.0;
    for (long k = 0; k < steps; k++) {
        check(api.get_real(c, &vr[OMEGA_M], 1, &w), "fmi2GetReal(omega_m)");
        double e = square(k, 1000, 5.0) - w;
        const fmi2Real tau[] = {kp * e + ki * integral, k >= 4000 ? -2.0 : 0.0};
        integral += H * e;
        set_inputs(c, k, tau);
        check(api.do_step(c, k * H, H, fmi2True), "fmi2DoStep");
        count_switch(c);
        if ((k + 1) % every == 0) sample(c, k + 1);
    }
    release(c);
}

/* Open loop to steps/2, the FMU state serialized into `path`, then the rest of the run. */
static void save(long steps, long every, const char *path) {
    fmi2Component c = make("save");
    long half = steps / 2;
    run_open(c, 0, half, steps);
    fmi2FMUstate state = NULL;
    size_t size = 0;
    check(api.get_state(c, &state), "fmi2GetFMUstate");
    check(api.serialized_size(c, state, &size), "fmi2SerializedFMUstateSize");
    fmi2Byte *bytes = malloc(size);
    if (!bytes) die("out of memory");
    check(api.serialize(c, state, bytes, size), "fmi2SerializeFMUstate");
    check(api.free_state(c, &state), "fmi2FreeFMUstate");
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(bytes, 1, size, f) != size || fclose(f) != 0) die("cannot write %s", path);
    free(bytes);
    printf("@ saved %lu\n", (unsigned long)size);
    switches = 0; /* counted from the saved state on, as restore counts them */
    run_open(c, half, steps, every);
    release(c);
}

/* A fresh instance takes the state saved at steps/2 (possibly by another platform), then runs the
 * rest of the open loop. The switch counter restarts from the restored contact. */
static void restore(long steps, long every, const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) die("cannot open %s", path);
    static fmi2Byte bytes[1 << 16];
    size_t size = fread(bytes, 1, sizeof bytes, f);
    if (ferror(f) || !feof(f)) die("cannot read %s (or larger than %lu bytes)", path, (unsigned long)sizeof bytes);
    fclose(f);
    fmi2Component c = make("restore");
    fmi2FMUstate state = NULL;
    check(api.deserialize(c, bytes, size, &state), "fmi2DeSerializeFMUstate");
    check(api.set_state(c, state), "fmi2SetFMUstate");
    check(api.free_state(c, &state), "fmi2FreeFMUstate");
    read_contacts(c, last_contact);
    switches = 0;
    run_open(c, steps / 2, steps, every);
    release(c);
}

/* Each call breaks a rule of FMI 2.0; its status is printed with the number of messages it
 * logged. A fresh instance is made for the calls that need one, and freed without
 * fmi2Terminate, which FMI 2.0 does not allow once a call has put the instance in error. */
static void report(const char *name, fmi2Status status, long before) {
    printf("@ misuse %s %d %ld\n", name, (int)status, messages - before);
}

static void misuse(void) {
    const fmi2ValueReference in[] = {vr[TAU_M]}, unknown[] = {4000000000u};
    fmi2Real value = 0.0, nan_value = 0.0;
    nan_value = nan_value / nan_value; /* a quiet NaN without libm */
    long before;

    before = messages;
    report("do_step_null_instance", api.do_step(NULL, 0.0, H, fmi2True), before);
    before = messages;
    report("get_real_null_instance", api.get_real(NULL, in, 1, &value), before);
    before = messages;
    report("set_real_null_instance", api.set_real(NULL, in, 1, &value), before);
    before = messages;
    report("terminate_null_instance", api.terminate(NULL), before);

    fmi2Component c = make("misuse");
    before = messages;
    report("do_step_nan_step", api.do_step(c, 0.0, nan_value, fmi2True), before);
    api.free_instance(c);

    c = make("misuse");
    before = messages;
    report("do_step_negative_step", api.do_step(c, 0.0, -H, fmi2True), before);
    api.free_instance(c);

    c = make("misuse");
    before = messages;
    report("do_step_wrong_time", api.do_step(c, 1.0, H, fmi2True), before);
    api.free_instance(c);

    c = make("misuse");
    before = messages;
    report("set_real_nan_input", api.set_real(c, in, 1, &nan_value), before);
    api.free_instance(c);

    c = make("misuse");
    before = messages;
    report("get_real_unknown_vr", api.get_real(c, unknown, 1, &value), before);
    api.free_instance(c);

    c = make("misuse");
    before = messages;
    static const fmi2Byte garbage[64] = {'B', 'K', 'L', 'S', 'H', 'F', 'M', 'U', 1};
    fmi2FMUstate state = NULL;
    report("deserialize_garbage", api.deserialize(c, garbage, sizeof garbage, &state), before);
    api.free_instance(c);

    c = api.instantiate("misuse", fmi2CoSimulation, token, "", &callbacks, fmi2False, fmi2False);
    if (!c) die("fmi2Instantiate returned NULL");
    before = messages;
    report("do_step_before_initialization", api.do_step(c, 0.0, H, fmi2True), before);
    api.free_instance(c);

    before = messages;
    c = api.instantiate("misuse", fmi2CoSimulation, "{not-the-guid}", "", &callbacks, fmi2False, fmi2False);
    printf("@ misuse instantiate_wrong_guid %s %ld\n", c ? "instance" : "null", messages - before);
    if (c) api.free_instance(c);

    /* The library is still usable after all of the above. */
    c = make("after-misuse");
    before = messages;
    report("fresh_instance_steps", api.do_step(c, 0.0, H, fmi2True), before);

    /* An importer that closes the library while an instance lives and opens it again (ecos does,
     * for two components of one FMU file): the instance steps on, and the next one gets a handle
     * of its own (the library stays loaded: build.rs, src/ffi/instantiate.rs). */
    close_library();
    load(library_path);
    fmi2Component d = make("after-reload");
    before = messages;
    report("step_after_reload", api.do_step(c, H, H, fmi2True), before);
    printf("@ misuse reload_distinct_handles %s %ld\n", c != d ? "distinct" : "same", messages - before);
    release(d);
    release(c);
}

static long positive(const char *text, const char *what) {
    char *end;
    long value = strtol(text, &end, 10);
    if (*end || value <= 0) die("%s must be a positive integer, got `%s`", what, text);
    return value;
}

/* The loop closed by the controller model of the same library (docs/model.md §9), values passed
 * after each step: over step k the drive gets the controller's torque after step k-1, the
 * controller the drive's motor speed after step k-1; the load torque as in the closed loop. */
static void controller_loop(long steps, long every, const char *guid, const char *refs, const char *params) {
    fmi2ValueReference speed_in, torque_out;
    if (sscanf(refs, "%u,%u", &speed_in, &torque_out) != 2) die("controller: expected <omega_m vr>,<tau_m vr>");
    fmi2ValueReference pvr[MAX_PARAMETERS];
    fmi2Real pvalue[MAX_PARAMETERS];
    size_t n = parse_bits(params, pvr, pvalue);
    fmi2Component plant = make("drive");
    fmi2Component pi = api.instantiate("controller", fmi2CoSimulation, guid, "", &callbacks, fmi2False, fmi2False);
    if (!pi) die("fmi2Instantiate(controller) returned NULL");
    check(api.set_real(pi, pvr, n, pvalue), "fmi2SetReal(controller parameters)");
    check(api.setup_experiment(pi, fmi2False, 0.0, 0.0, fmi2False, 0.0), "fmi2SetupExperiment(controller)");
    check(api.enter_init(pi), "fmi2EnterInitializationMode(controller)");
    check(api.exit_init(pi), "fmi2ExitInitializationMode(controller)");
    for (long k = 0; k < steps; k++) {
        fmi2Real w, u;
        check(api.get_real(plant, &vr[OMEGA_M], 1, &w), "fmi2GetReal(omega_m)");
        check(api.get_real(pi, &torque_out, 1, &u), "fmi2GetReal(controller tau_m)");
        const fmi2Real tau[] = {u, k >= 4000 ? -2.0 : 0.0};
        set_inputs(plant, k, tau);
        check(api.set_real(pi, &speed_in, 1, &w), "fmi2SetReal(controller omega_m)");
        check(api.do_step(plant, k * H, H, fmi2True), "fmi2DoStep");
        check(api.do_step(pi, k * H, H, fmi2True), "fmi2DoStep(controller)");
        count_switch(plant);
        if ((k + 1) % every == 0) sample(plant, k + 1);
    }
    release(pi);
    release(plant);
}

int main(int argc, char **argv) {
    if (argc < 6)
        die("usage: host <library> <token> <variables> <parameters> closed|open|save|restore|misuse|fmi3|controller "
            "[args]");
    verbose = getenv("CROSS_HOST_VERBOSE") != NULL;
    load(argv[1]);
    token = argv[2];
    parse_variables(argv[3]);
    parse_parameters(argv[4]);
    const char *scenario = argv[5];
    if (strcmp(scenario, "closed") == 0 && argc == 8) {
        closed_loop(positive(argv[6], "steps"), positive(argv[7], "every"));
    } else if (strcmp(scenario, "open") == 0 && argc == 8) {
        open_loop(positive(argv[6], "steps"), positive(argv[7], "every"));
    } else if (strcmp(scenario, "save") == 0 && argc == 9) {
        save(positive(argv[6], "steps"), positive(argv[7], "every"), argv[8]);
    } else if (strcmp(scenario, "restore") == 0 && argc == 9) {
        restore(positive(argv[6], "steps"), positive(argv[7], "every"), argv[8]);
    } else if (strcmp(scenario, "misuse") == 0 && argc == 6) {
        misuse();
    } else if (strcmp(scenario, "fmi3") == 0 && argc == 8) {
        fmi3_open_loop(positive(argv[6], "steps"), positive(argv[7], "every"));
    } else if (strcmp(scenario, "controller") == 0 && argc == 11) {
        controller_loop(positive(argv[6], "steps"), positive(argv[7], "every"), argv[8], argv[9], argv[10]);
    } else {
        die("unknown scenario or wrong argument count: %s", scenario);
    }
    return fflush(stdout) == 0 ? 0 : 1;
}
