/* Timing harness for one robotgen-generated C library (bench/run.py compiles and runs it).
 *
 * Compiled as (run.py does this):
 *   cc -std=c99 -O2 -DRG_HEADER='"puma560.h"' -DRG_PREFIX=puma560 -DRG_NQ=6 \
 *      -I OUT bench/harness.c OUT/<generated kernels>.c -lm
 * -O2 only, no -march=native: the numbers are what a user gets from a portable build.
 *
 * For each function: NSETS random input sets (deterministic LCG, angles in [-pi, pi],
 * velocities and accelerations in [-2, 2]) are cycled through, so the kernel cannot be
 * specialised to one input; one output element per call is added to an accumulator that
 * is finally stored to a volatile, so the calls cannot be dropped as dead code (the kernels
 * live in another translation unit and are not inlined without LTO anyway). The loop is
 * calibrated to take >= ~50 ms, repeated REPEATS times; min and median ns per call printed
 * as "name min_ns median_ns iterations", one line per function. "harness serial f..." times
 * one call at a time (below); "harness calibrate" measures the machine's floor.
 */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <time.h>

#include RG_HEADER

#ifndef RG_NQ
#error "define RG_NQ (number of joint coordinates)"
#endif
#ifndef RG_PREFIX
#error "define RG_PREFIX (the module name, the C prefix)"
#endif

#define RG_CAT_(a, b) a##_##b
#define RG_CAT(a, b) RG_CAT_(a, b)
#define FN(f) RG_CAT(RG_PREFIX, f)

#define NQ RG_NQ
#define NSETS 256 /* power of two */
#define REPEATS 7
#define MIN_NS 5.0e7

static double Q[NSETS][NQ], QD[NSETS][NQ], QDD[NSETS][NQ];
static double OUT[8 * NQ * NQ + 8 * NQ + 16];
static volatile double sink;

static double now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e9 + (double)t.tv_nsec;
}

static unsigned long long lcg_state = 88172645463325252ULL;
static double uniform(double lo, double hi) {
    lcg_state = lcg_state * 6364136223846793005ULL + 1442695040888963407ULL;
    return lo + (hi - lo) * (double)(lcg_state >> 11) * (1.0 / 9007199254740992.0);
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* One call at a time (harness argument "serial"): on x86 an lfence after each call keeps the
 * next call from starting before this one has finished, as when a Python call (or a servo
 * loop's other work) separates them. Without it the out-of-order core overlaps consecutive
 * independent calls, and the loop measures throughput. Elsewhere only a compiler barrier. */
static int serial;
#if defined(__x86_64__) || defined(__i386__)
#define RG_SERIALIZE() __asm__ __volatile__("lfence" ::: "memory")
#else
#define RG_SERIALIZE() __asm__ __volatile__("" ::: "memory")
#endif

/* The timed loop: ITERS calls of CALL on the input sets in turn (s), each output summed. */
#define BENCH_LOOP(CALL, outsize, AFTER)                                        \
    for (it = 0; it < iters; it++) {                                            \
        int s = (int)(it & (NSETS - 1));                                        \
        CALL;                                                                   \
        acc += OUT[it % (outsize)];                                             \
        AFTER;                                                                  \
    }

#define BENCH_TIMED(CALL, outsize)                                              \
    do {                                                                        \
        t0 = now_ns();                                                          \
        if (serial) {                                                           \
            BENCH_LOOP(CALL, outsize, RG_SERIALIZE())                           \
        } else {                                                                \
            BENCH_LOOP(CALL, outsize, (void)0)                                  \
        }                                                                       \
        t1 = now_ns();                                                          \
    } while (0)

/* CALL uses s (the input set) and writes OUT; outsize = number of outputs written. */
#define BENCH(label, outsize, CALL)                                              \
    do {                                                                        \
        long iters = 1000, it;                                                  \
        double t0, t1, acc = 0.0, times[REPEATS];                               \
        int r;                                                                  \
        for (;;) { /* calibrate */                                              \
            BENCH_TIMED(CALL, outsize);                                         \
            if (t1 - t0 >= MIN_NS || iters > (1L << 30)) break;                 \
            iters *= 2;                                                         \
        }                                                                       \
        for (r = 0; r < REPEATS; r++) {                                         \
            BENCH_TIMED(CALL, outsize);                                         \
            times[r] = (t1 - t0) / (double)iters;                               \
        }                                                                       \
        sink += acc;                                                            \
        qsort(times, REPEATS, sizeof times[0], cmp_double);                     \
        printf("%s %.3f %.3f %ld\n", label, times[0], times[REPEATS / 2], iters); \
        fflush(stdout);                                                         \
    } while (0)

static int selected(int argc, char **argv, const char *name) {
    int i;
    if (argc < 2) return 1;
    for (i = 1; i < argc; i++)
        if (strcmp(argv[i], name) == 0) return 1;
    return 0;
}

/* The machine's scalar floor, measured: "peak_ops_per_ns": multiply-add chains, 12 independent
 * (enough to fill the floating-point pipes at -O2, scalar code); "sincos_ns": one sin and one
 * cos of the same angle from libm, on the harness's angles. bench/run.py divides a kernel's
 * floor (its operations at the peak plus its sin/cos pairs at that cost) by its time. */
static void calibrate(void) {
    double a[12], best = 1e30, t0, t1;
    long it, iters = 1L << 22;
    int r, k;
    for (r = 0; r < REPEATS; r++) {
        double a0 = 1.0, a1 = 1.1, a2 = 1.2, a3 = 1.3, a4 = 1.4, a5 = 1.5, a6 = 1.6, a7 = 1.7, a8 = 1.8,
               a9 = 1.9, a10 = 2.0, a11 = 2.1;
        const double m = 0.999999999, c = 1e-9;
        t0 = now_ns();
        for (it = 0; it < iters; it++) {
            a0 = a0 * m + c; a1 = a1 * m + c; a2 = a2 * m + c; a3 = a3 * m + c;
            a4 = a4 * m + c; a5 = a5 * m + c; a6 = a6 * m + c; a7 = a7 * m + c;
            a8 = a8 * m + c; a9 = a9 * m + c; a10 = a10 * m + c; a11 = a11 * m + c;
        }
        t1 = now_ns();
        a[0] = a0; a[1] = a1; a[2] = a2; a[3] = a3; a[4] = a4; a[5] = a5; a[6] = a6; a[7] = a7; a[8] = a8;
        a[9] = a9; a[10] = a10; a[11] = a11;
        for (k = 0; k < 12; k++) sink += a[k];
        if (t1 - t0 < best) best = t1 - t0;
    }
    printf("peak_ops_per_ns %.4f\n", 24.0 * (double)iters / best);
    best = 1e30;
    for (r = 0; r < REPEATS; r++) {
        double acc = 0.0;
        t0 = now_ns();
        for (it = 0; it < iters / 16; it++) {
            double x = Q[it & (NSETS - 1)][it % NQ];
            acc += sin(x) * cos(x);
        }
        t1 = now_ns();
        sink += acc;
        if (t1 - t0 < best) best = t1 - t0;
    }
    printf("sincos_ns %.4f\n", best / (double)(iters / 16));
}

int main(int argc, char **argv) {
    int s, i;
    for (s = 0; s < NSETS; s++)
        for (i = 0; i < NQ; i++) {
            Q[s][i] = uniform(-3.141592653589793, 3.141592653589793);
            QD[s][i] = uniform(-2.0, 2.0);
            QDD[s][i] = uniform(-2.0, 2.0);
        }
    if (argc > 1 && strcmp(argv[1], "calibrate") == 0) {
        calibrate();
        return 0;
    }
    if (argc > 1 && strcmp(argv[1], "serial") == 0) {
        serial = 1;
        --argc;
        ++argv;
    }
    if (selected(argc, argv, "mass")) BENCH("mass", NQ * NQ, FN(mass)(Q[s], OUT));
    if (selected(argc, argv, "inverse_dynamics"))
        BENCH("inverse_dynamics", NQ, FN(inverse_dynamics)(Q[s], QD[s], QDD[s], OUT));
    if (selected(argc, argv, "jacobian")) BENCH("jacobian", 6 * NQ, FN(jacobian)(Q[s], OUT));
    if (selected(argc, argv, "gravity")) BENCH("gravity", NQ, FN(gravity)(Q[s], OUT));
    if (selected(argc, argv, "coriolis")) BENCH("coriolis", NQ * NQ, FN(coriolis)(Q[s], QD[s], OUT));
    if (selected(argc, argv, "forward_dynamics"))
        BENCH("forward_dynamics", NQ, FN(forward_dynamics)(Q[s], QD[s], QDD[s], OUT));
    if (selected(argc, argv, "fk")) BENCH("fk", 16, FN(fk)(Q[s], OUT));
    /* a computed-torque cycle's terms: one fused call against the four separate ones */
    if (selected(argc, argv, "servo_terms"))
        BENCH("servo_terms", NQ * NQ + NQ + 6 * NQ + 6,
              FN(servo_terms)(Q[s], QD[s], OUT, OUT + NQ * NQ, OUT + NQ * NQ + NQ, OUT + NQ * NQ + 7 * NQ));
    if (selected(argc, argv, "servo_terms_separate"))
        BENCH("servo_terms_separate", NQ * NQ + NQ + 6 * NQ + 6,
              (FN(mass)(Q[s], OUT), FN(nonlinear)(Q[s], QD[s], OUT + NQ * NQ),
               FN(jacobian)(Q[s], OUT + NQ * NQ + NQ),
               FN(jacobian_dot_qd)(Q[s], QD[s], OUT + NQ * NQ + 7 * NQ)));
#ifdef RG_DERIVATIVES /* the module has the derivative functions */
    if (selected(argc, argv, "inverse_dynamics_derivatives"))
        BENCH("inverse_dynamics_derivatives", 2 * NQ * NQ,
              FN(inverse_dynamics_derivatives)(Q[s], QD[s], QDD[s], OUT, OUT + NQ * NQ));
    if (selected(argc, argv, "forward_dynamics_derivatives"))
        BENCH("forward_dynamics_derivatives", 3 * NQ * NQ,
              FN(forward_dynamics_derivatives)(Q[s], QD[s], QDD[s], OUT, OUT + NQ * NQ, OUT + 2 * NQ * NQ));
    if (selected(argc, argv, "mass_inverse")) BENCH("mass_inverse", NQ * NQ, FN(mass_inverse)(Q[s], OUT));
    if (selected(argc, argv, "discrete_dynamics_derivatives")) {
        static const double dt = 1e-3;
        BENCH("discrete_dynamics_derivatives", 6 * NQ * NQ + 2 * NQ,
              FN(discrete_dynamics_derivatives)(Q[s], QD[s], QDD[s], &dt, OUT, OUT + NQ, OUT + 2 * NQ,
                                                OUT + 2 * NQ + 4 * NQ * NQ));
    }
    if (selected(argc, argv, "jacobian_derivative"))
        BENCH("jacobian_derivative", 6 * NQ, FN(jacobian_derivative)(Q[s], QD[s], OUT));
#endif
    return sink == 12345.678 ? 1 : 0; /* use sink so it is observable */
}
