/* FMI 2.0 Co-Simulation host of the cross-platform test (xtask/src/cross/): the same program is
 * compiled for every platform the FMU ships (cc for linux64, x86_64-w64-mingw32-gcc for win64
 * under Wine, aarch64-linux-gnu-gcc under qemu), loads one platform's library and prints what it
 * observed, one result per line:
 *
 *     @ sample <k> <contact> <switches> <bits of theta_m omega_m theta_L omega_L psi bound bound_paper>
 *     @ misuse <case> <status> <messages logged>
 *     @ saved <size in bytes>
 *
 * Reals are printed as the hexadecimal IEEE-754 bits, so that the comparison of two platforms in
 * xtask sees every bit. The host computes its inputs with +, - and * only (no libm, no fused
 * multiply-add: built with -ffp-contract=off), so every platform feeds the FMU identical inputs.
 *
 * usage: host <library> <guid> <variables> <parameters> <scenario> [args]
 *   <variables>   name=vr,... for tau_m tau_L theta_m omega_m theta_L omega_L psi bound
 *                 bound_paper contact Kp Ki (read by xtask from the archive's modelDescription.xml)
 *   <parameters>  vr=bits,... Real parameters set before initialization, each value as the
 *                 hexadecimal IEEE-754 bits (no platform's decimal conversion enters the run);
 *                 must include Kp and Ki, which are also the gains of the host's PI loop
 *   closed <steps> <every>           PI loop on omega_m, square-wave reference, load step
 *   open <steps> <every>             square-wave motor torque, no controller
 *   save <steps> <every> <file>      open loop: fmi2SerializeFMUstate at steps/2 into <file>,
 *                                    then the samples of the rest of the run
 *   restore <steps> <every> <file>   a fresh instance restores <file> and runs the rest
 *   misuse                           calls FMI 2.0 forbids, and the status each gets
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

static void open_library(const char *path) {
#ifdef _WIN32
    library = (void *)LoadLibraryA(path);
    if (!library) die("LoadLibrary %s failed (error %lu)", path, (unsigned long)GetLastError());
#else
    library = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!library) die("dlopen %s: %s", path, dlerror());
#endif
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
}

/* ---- value references, by name ---- */

enum { TAU_M, TAU_L, THETA_M, OMEGA_M, THETA_L, OMEGA_L, PSI, BOUND, BOUND_PAPER, CONTACT, KP, KI, NVARS };
static const char *const var_name[NVARS] = {"tau_m", "tau_L", "theta_m", "omega_m",     "theta_L", "omega_L",
                                            "psi",   "bound", "bound_paper", "contact", "Kp",      "Ki"};
static fmi2ValueReference vr[NVARS];

/* Parses "name=vr,name=vr,..."; every name of var_name must be given. */
static void parse_variables(const char *list) {
    int seen[NVARS] = {0};
    const char *p = list;
    while (*p) {
        const char *eq = strchr(p, '='), *end = strchr(p, ',');
        if (!end) end = p + strlen(p);
        if (!eq || eq > end) die("variables: expected name=vr in `%s`", p);
        for (int i = 0; i < NVARS; i++) {
            if ((size_t)(eq - p) == strlen(var_name[i]) && strncmp(p, var_name[i], eq - p) == 0) {
                char *stop;
                unsigned long value = strtoul(eq + 1, &stop, 10);
                if (stop != end) die("variables: value reference of %s is not a number", var_name[i]);
                vr[i] = (fmi2ValueReference)value;
                seen[i] = 1;
            }
        }
        p = *end ? end + 1 : end;
    }
    for (int i = 0; i < NVARS; i++)
        if (!seen[i]) die("variables: no value reference for %s", var_name[i]);
}

/* Parameters: value references and values, parsed from "vr=bits,..."; kp, ki among them. */
#define MAX_PARAMETERS 32
static fmi2ValueReference param_vr[MAX_PARAMETERS];
static fmi2Real param_value[MAX_PARAMETERS];
static size_t n_params;
static double kp, ki;

static void parse_parameters(const char *list) {
    int have_kp = 0, have_ki = 0;
    const char *p = list;
    while (*p) {
        if (n_params == MAX_PARAMETERS) die("parameters: more than %d", MAX_PARAMETERS);
        char *eq, *end;
        unsigned long ref = strtoul(p, &eq, 10);
        if (eq == p || *eq != '=') die("parameters: expected vr=bits in `%s`", p);
        uint64_t bits = (uint64_t)strtoull(eq + 1, &end, 16);
        if (end == eq + 1 || (*end && *end != ',')) die("parameters: expected hexadecimal bits in `%s`", p);
        double value;
        memcpy(&value, &bits, sizeof value);
        param_vr[n_params] = (fmi2ValueReference)ref;
        param_value[n_params++] = value;
        if (ref == vr[KP]) kp = value, have_kp = 1;
        if (ref == vr[KI]) ki = value, have_ki = 1;
        p = *end ? end + 1 : end;
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

static const char *guid;

static void check(fmi2Status s, const char *what) {
    if (s != fmi2OK) die("%s returned status %d", what, (int)s);
}

/* An initialized instance with the given parameters. */
static fmi2Component make(const char *name) {
    fmi2Component c = api.instantiate(name, fmi2CoSimulation, guid, "", &callbacks, fmi2False, fmi2False);
    if (!c) die("fmi2Instantiate(%s) returned NULL", name);
    check(api.set_real(c, param_vr, n_params, param_value), "fmi2SetReal(parameters)");
    check(api.setup_experiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), "fmi2SetupExperiment");
    check(api.enter_init(c), "fmi2EnterInitializationMode");
    check(api.exit_init(c), "fmi2ExitInitializationMode");
    return c;
}

static void release(fmi2Component c) {
    check(api.terminate(c), "fmi2Terminate");
    api.free_instance(c);
}

/* ---- what is compared: every output at sample points, and the contact switches ---- */

static uint64_t bits(double x) {
    uint64_t b;
    memcpy(&b, &x, sizeof b);
    return b;
}

static fmi2Integer last_contact;
static long switches;

static void count_switch(fmi2Component c) {
    fmi2Integer contact;
    check(api.get_integer(c, &vr[CONTACT], 1, &contact), "fmi2GetInteger(contact)");
    if (contact != last_contact) switches++;
    last_contact = contact;
}

static void sample(fmi2Component c, long k) {
    const fmi2ValueReference out_vr[] = {vr[THETA_M], vr[OMEGA_M], vr[THETA_L], vr[OMEGA_L],
                                         vr[PSI],     vr[BOUND],   vr[BOUND_PAPER]};
    fmi2Real out[7];
    check(api.get_real(c, out_vr, 7, out), "fmi2GetReal(outputs)");
    printf("@ sample %ld %d %ld", k, (int)last_contact, switches);
    for (int i = 0; i < 7; i++) printf(" %016" PRIx64, bits(out[i]));
    printf("\n");
}

/* ---- scenarios ---- */

/* Square wave of amplitude a and period 2 half_period steps: the sign flips every half_period. */
static double square(long k, long half_period, double a) { return (k / half_period) % 2 == 0 ? a : -a; }

/* Open loop: the motor torque reverses every 0.4 s, so the motor crosses the gap and takes up
 * the other flank again and again (contact made and lost); a load torque from t = 1 s. */
static void open_inputs(fmi2Component c, long k) {
    const fmi2ValueReference in[] = {vr[TAU_M], vr[TAU_L]};
    const fmi2Real tau[] = {square(k, 400, 3.0), k >= 1000 ? -0.5 : 0.0};
    check(api.set_real(c, in, 2, tau), "fmi2SetReal(inputs)");
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

/* Closed loop: a sampled PI on the motor speed (the FMU's Kp, Ki) tracks a reference that
 * reverses between +5 and -5 rad/s every second; a load torque of -2 N.m from t = 4 s. */
static void closed_loop(long steps, long every) {
    fmi2Component c = make("closed");
    const fmi2ValueReference in[] = {vr[TAU_M], vr[TAU_L]};
    double integral = 0.0, w = 0.0;
    for (long k = 0; k < steps; k++) {
        check(api.get_real(c, &vr[OMEGA_M], 1, &w), "fmi2GetReal(omega_m)");
        double e = square(k, 1000, 5.0) - w;
        const fmi2Real tau[] = {kp * e + ki * integral, k >= 4000 ? -2.0 : 0.0};
        integral += H * e;
        check(api.set_real(c, in, 2, tau), "fmi2SetReal(inputs)");
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
    check(api.get_integer(c, &vr[CONTACT], 1, &last_contact), "fmi2GetInteger(contact)");
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

    c = api.instantiate("misuse", fmi2CoSimulation, guid, "", &callbacks, fmi2False, fmi2False);
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
    release(c);
}

static long positive(const char *text, const char *what) {
    char *end;
    long value = strtol(text, &end, 10);
    if (*end || value <= 0) die("%s must be a positive integer, got `%s`", what, text);
    return value;
}

int main(int argc, char **argv) {
    if (argc < 6) die("usage: host <library> <guid> <variables> <parameters> closed|open|save|restore|misuse [args]");
    verbose = getenv("CROSS_HOST_VERBOSE") != NULL;
    load(argv[1]);
    guid = argv[2];
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
    } else {
        die("unknown scenario or wrong argument count: %s", scenario);
    }
    return fflush(stdout) == 0 ? 0 : 1;
}
