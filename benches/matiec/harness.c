/* The C main of the matiec column of `cargo bench --bench st_native`: one workload's program,
 * compiled by matiec's iec2c (benches/matiec/build, which names the workload with
 * -DWORKLOAD_<name>), run as OpenPLC's runtime runs a program: config_init__() once, then each
 * cycle config_run__(tick) with the tick counting up, and __CURRENT_TIME advanced by the task's
 * tick after it (OpenPLC_v3: webserver/core/main.cpp, and the updateTime() its
 * glue_generator writes).
 *
 *   harness CHECKS
 *
 * prints, after each of the first CHECKS scans, one line "scan K NAME=SLOT ...": the variables
 * the bench compares with plcd's, named as plcd names them, each in the encoding of plcd's
 * variable slots (hex; signed values sign-extended to 64 bits, BOOL 0 or 1, REAL the bits of
 * the float); then "ns_per_scan X": the median time of one scan over batches of scans, with
 * CLOCK_MONOTONIC. The variables are read through matiec's generated structures (POUS.h) and
 * its accessor macros (accessor.h). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "iec_std_lib.h"
#include "accessor.h"
#include "POUS.h"

/* What the runtime defines for the generated code; iec_std_lib.h declares them. */
TIME __CURRENT_TIME;
BOOL __DEBUG;

/* Config0.c's. */
extern unsigned long long common_ticktime__;
void config_init__(void);
void config_run__(unsigned long tick);

static unsigned long tick;

/* One PLC cycle, as OpenPLC's main loop runs it. */
static void cycle(void) {
    config_run__(tick++);
    __CURRENT_TIME.tv_sec += common_ticktime__ / 1000000000ULL;
    __CURRENT_TIME.tv_nsec += common_ticktime__ % 1000000000ULL;
    if (__CURRENT_TIME.tv_nsec >= 1000000000) {
        __CURRENT_TIME.tv_nsec -= 1000000000;
        __CURRENT_TIME.tv_sec += 1;
    }
}

static void put(const char *name, int64_t slot) {
    printf(" %s=%llx", name, (unsigned long long)slot);
}

/* An element, or an element's member: NAME[INDEX] or NAME[INDEX].MEMBER. */
static void put_at(const char *name, int index, const char *member, int64_t slot) {
    char full[64];
    snprintf(full, sizeof full, "%s[%d]%s%s", name, index, *member ? "." : "", member);
    put(full, slot);
}

static int64_t real(REAL r) {
    uint32_t bits;
    memcpy(&bits, &r, sizeof bits);
    return bits;
}

/* Each workload: its program instance (Res0.c's RES0__INSTANCE0, of the PROGRAM's type),
 * set_inputs() as plcd's bench sets them before the first scan (benches/common/st_workloads.rs,
 * case), and put_variables(). */
#define V(var) __GET_VAR(RES0__INSTANCE0.var, )
#define SET(var, value) __SET_VAR(RES0__INSTANCE0., var, , value)

#if defined(WORKLOAD_bit)
extern BITS RES0__INSTANCE0;

/* BIT_INPUTS and BIT_SENSORS. */
static void set_inputs(void) {
    SET(START, 1);
    SET(STOP, 0);
    SET(ESTOP, 0);
    SET(GUARD, 1);
    SET(READY, 1);
    SET(AUTO, 1);
    SET(MANUAL, 0);
    SET(JOG, 0);
    SET(S1, 1);
    SET(S2, 1);
    SET(S3, 1);
    SET(S4, 0);
    SET(S5, 1);
    SET(S6, 0);
    SET(S7, 0);
    SET(S8, 1);
}

static void put_variables(void) {
    put("run", V(RUN)), put("fault", V(FAULT));
    put("s1_before", V(S1_BEFORE)), put("s1_rise", V(S1_RISE)), put("flip", V(FLIP));
    put("m1", V(M1)), put("m2", V(M2)), put("m3", V(M3));
    put("m4", V(M4)), put("m5", V(M5)), put("m6", V(M6));
    put("q1", V(Q1)), put("q2", V(Q2)), put("q3", V(Q3)), put("q4", V(Q4));
    put("q5", V(Q5)), put("q6", V(Q6)), put("q7", V(Q7)), put("q8", V(Q8));
}

#elif defined(WORKLOAD_int_loops)
extern INTLOOPS RES0__INSTANCE0;

static void set_inputs(void) {}

static void put_variables(void) {
    put("i", V(I)), put("j", V(J));
    put("acc", V(ACC)), put("odd", V(ODD)), put("total", V(TOTAL));
}

#elif defined(WORKLOAD_pid)
extern PIDLOOPS RES0__INSTANCE0;

static void set_inputs(void) {}

/* ARRAY [1..100]: matiec's table starts at 0. */
static void put_variables(void) {
    for (int i = 1; i <= 100; i++) {
        put_at("pv", i, "", real(V(PV).table[i - 1]));
        put_at("loops", i, "out", real(V(LOOPS).table[i - 1].OUT));
        put_at("loops", i, "integral", real(V(LOOPS).table[i - 1].INTEGRAL));
        put_at("loops", i, "prev_err", real(V(LOOPS).table[i - 1].PREV_ERR));
    }
}

#elif defined(WORKLOAD_sort)
extern SORT RES0__INSTANCE0;

static void set_inputs(void) {}

static void put_variables(void) {
    put("seed", V(SEED));
    for (int i = 0; i < 100; i++)
        put_at("a", i, "", V(A).table[i]);
}

#elif defined(WORKLOAD_state_machine)
extern MACHINES RES0__INSTANCE0;

static void set_inputs(void) {}

/* The phase as plcd holds an enumeration: its position in the list (matiec's C enum). */
static void put_variables(void) {
    for (int i = 0; i < 32; i++) {
        STATIONVARS s = V(ST).table[i];
        put_at("level", i, "", V(LEVEL).table[i]);
        put_at("temp", i, "", V(TEMP).table[i]);
        put_at("st", i, "phase", s.PHASE);
        put_at("st", i, "ticks", s.TICKS);
        put_at("st", i, "batches", s.BATCHES);
        put_at("st", i, "alarm", s.ALARM);
        put_at("st", i, "valve_in", s.VALVE_IN);
        put_at("st", i, "heater", s.HEATER);
        put_at("st", i, "valve_out", s.VALVE_OUT);
    }
}

#else
#error "no workload: build with -DWORKLOAD_<name> (benches/matiec/build)"
#endif

static double now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec * 1e9 + t.tv_nsec;
}

static int by_value(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Batches long enough (1 ms at least) that the clock's cost and resolution do not count. */
enum { BATCHES = 301, MIN_BATCH_NS = 1000000 };

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s CHECKS\n", argv[0]);
        return 2;
    }
    long checks = strtol(argv[1], NULL, 10);
    config_init__();
    set_inputs();
    for (long k = 1; k <= checks; k++) {
        cycle();
        printf("scan %ld", k);
        put_variables();
        printf("\n");
    }

    long batch = 1;
    for (;;) {
        double start = now_ns();
        for (long k = 0; k < batch; k++)
            cycle();
        if (now_ns() - start >= MIN_BATCH_NS)
            break;
        batch *= 2;
    }
    static double per_scan[BATCHES];
    for (int b = 0; b < BATCHES; b++) {
        double start = now_ns();
        for (long k = 0; k < batch; k++)
            cycle();
        per_scan[b] = (now_ns() - start) / batch;
    }
    qsort(per_scan, BATCHES, sizeof per_scan[0], by_value);
    printf("ns_per_scan %.3f\n", per_scan[BATCHES / 2]);
    return 0;
}
