/* A fixed-rate servo loop around robotgen's emitted C, as a controller binary would run it.
 *
 *   make controller                          (builds ./examples/controller/puma560_ct and styx_ct)
 *   examples/controller/puma560_ct [--rate HZ] [--cycles N] [--help]
 *   examples/controller/styx_ct    [--rate HZ] [--cycles N] [--help]
 *
 * Each cycle, on an absolute schedule (clock_nanosleep TIMER_ABSTIME, so lateness does not
 * accumulate): read the state of a simulated plant, compute the torques, hand them to the plant,
 * which integrates its own dynamics over one period (the emitted forward_dynamics or
 * plant_dynamics, RK4) inside this binary. SCHED_FIFO and mlockall are asked for; where they are
 * not permitted the loop runs anyway and says so.
 *
 * PUMA (CHAIN): computed torque, tau = M (qdd_d + Kv (qd_d - qd) + Kp (q_d - q)) + C qd + N, from
 * the emitted servo_terms; the joints follow a sine about their zero posture.
 * Styx (TREE): the tree's emitted servo_step (computed torque at the hand, Deno et al. 1990) follows
 * the spec's hand trajectory; the plant is the constrained hand (plant_dynamics).
 *
 * Printed at the end: the tracking error, the period jitter (actual wake-up minus scheduled, min /
 * median / p99 / max) and the servo computation's time (median and worst case) over every cycle.
 * Statuses of the checked functions are honoured: a nonzero status stops the loop with a message.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <math.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>

#ifdef CHAIN
#include "puma560.h"
#define NQ PUMA560_NQ
#else
#include "styx_high_ct.h"
#define NQ STYX_HIGH_CT_NQ
#define NV STYX_HIGH_CT_PLANT_DYNAMICS_V_SIZE
#define NS STYX_HIGH_CT_SERVO_STEP_STATE_SIZE
#endif

#define NS_PER_S 1000000000LL

static long long now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (long long)t.tv_sec * NS_PER_S + t.tv_nsec;
}

static int cmp_ll(const void *a, const void *b) {
    long long x = *(const long long *)a, y = *(const long long *)b;
    return (x > y) - (x < y);
}

static void report(const char *what, long long *v, long n) {
    qsort(v, (size_t)n, sizeof v[0], cmp_ll);
    printf("%-22s min %8.2f  median %8.2f  p99 %8.2f  max %8.2f us\n", what, v[0] / 1e3, v[n / 2] / 1e3,
           v[(long)(0.99 * (double)(n - 1))] / 1e3, v[n - 1] / 1e3);
}

static void fail(const char *fn, int status, long cycle) {
    fprintf(stderr, "controller: %s returned %d at cycle %ld (%s); stopping\n", fn, status, cycle,
            status == 1 ? "a NaN or infinite input" : "a result that is not finite");
    exit(1);
}

#ifdef CHAIN
/* The plant: x = (q, qd), xdot = (qd, forward_dynamics(q, qd, tau)), RK4 over dt. */
static void plant_step(double *q, double *qd, const double *tau, double dt, long cycle) {
    double k[4][2][NQ], qs[NQ], qds[NQ];
    static const double c[4] = {0.0, 0.5, 0.5, 1.0};
    int s, i, status;
    for (s = 0; s < 4; ++s) {
        for (i = 0; i < NQ; ++i) {
            qs[i] = q[i] + (s ? c[s] * dt * k[s - 1][0][i] : 0.0);
            qds[i] = qd[i] + (s ? c[s] * dt * k[s - 1][1][i] : 0.0);
            k[s][0][i] = qds[i];
        }
        if ((status = puma560_forward_dynamics(qs, qds, tau, k[s][1])) != 0) fail("forward_dynamics", status, cycle);
    }
    for (i = 0; i < NQ; ++i) {
        q[i] += dt / 6.0 * (k[0][0][i] + 2 * k[1][0][i] + 2 * k[2][0][i] + k[3][0][i]);
        qd[i] += dt / 6.0 * (k[0][1][i] + 2 * k[1][1][i] + 2 * k[2][1][i] + k[3][1][i]);
    }
}
#else
static void plant_step(double *theta, double *v, const double *tau, double dt, long cycle) {
    double kt[4][NQ], kv[4][NV], th[NQ], vv[NV];
    static const double c[4] = {0.0, 0.5, 0.5, 1.0};
    int s, i, status;
    for (s = 0; s < 4; ++s) {
        for (i = 0; i < NQ; ++i) th[i] = theta[i] + (s ? c[s] * dt * kt[s - 1][i] : 0.0);
        for (i = 0; i < NV; ++i) vv[i] = v[i] + (s ? c[s] * dt * kv[s - 1][i] : 0.0);
        if ((status = styx_high_ct_plant_dynamics(th, vv, tau, kt[s], kv[s])) != 0) fail("plant_dynamics", status, cycle);
    }
    for (i = 0; i < NQ; ++i) theta[i] += dt / 6.0 * (kt[0][i] + 2 * kt[1][i] + 2 * kt[2][i] + kt[3][i]);
    for (i = 0; i < NV; ++i) v[i] += dt / 6.0 * (kv[0][i] + 2 * kv[1][i] + 2 * kv[2][i] + kv[3][i]);
}
#endif

static void usage(FILE *to, const char *program) {
    fprintf(to, "usage: %s [--rate HZ] [--cycles N]\n\n"
                "A fixed-rate servo loop around robotgen's emitted C (%s) against a simulated plant:\n"
                "prints the tracking error, the period jitter and the servo computation's time.\n\n"
                "  --rate HZ     servo rate, > 0 (default 1000)\n"
                "  --cycles N    cycles to run, >= 1 (default 100000)\n"
                "  -h, --help    this text\n", program,
#ifdef CHAIN
            "the PUMA 560's computed torque"
#else
            "the Styx hand's servo_step"
#endif
    );
}

/* Reads the value of option argv[*i] into *value; 0, or 2 (a usage error, said on stderr). */
static int option_value(int argc, char **argv, int *i, int integer, double *value) {
    char *end;
    if (*i + 1 >= argc) {
        fprintf(stderr, "controller: %s needs a value\n", argv[*i]);
        return 2;
    }
    ++*i;
    errno = 0;
    *value = integer ? (double)strtol(argv[*i], &end, 10) : strtod(argv[*i], &end);
    if (end == argv[*i] || *end != '\0' || errno != 0) {
        fprintf(stderr, "controller: %s takes %s, got '%s'\n", argv[*i - 1], integer ? "an integer" : "a number",
                argv[*i]);
        return 2;
    }
    return 0;
}

int main(int argc, char **argv) {
    double rate = 1000.0, value;
    long cycles = 100000, k;
    int i;
    for (i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) { usage(stdout, argv[0]); return 0; }
        if (strcmp(argv[i], "--rate") == 0) {
            if (option_value(argc, argv, &i, 0, &value) != 0) return 2;
            rate = value;
        } else if (strcmp(argv[i], "--cycles") == 0) {
            if (option_value(argc, argv, &i, 1, &value) != 0) return 2;
            cycles = (long)value;
        } else {
            fprintf(stderr, "controller: unknown argument '%s'\n", argv[i]);
            usage(stderr, argv[0]);
            return 2;
        }
    }
    if (!(rate > 0) || !isfinite(rate) || cycles < 1) {
        fprintf(stderr, "controller: --rate and --cycles must be positive\n");
        return 2;
    }
    const double dt = 1.0 / rate;
    const long long period = (long long)(NS_PER_S / rate);
    long long *late = malloc((size_t)cycles * sizeof *late), *busy = malloc((size_t)cycles * sizeof *busy);
    if (late == NULL || busy == NULL) { fprintf(stderr, "controller: out of memory\n"); return 1; }
    /* real-time setup, allocations done: nothing below allocates */
    struct sched_param sp = {.sched_priority = 80};
    if (sched_setscheduler(0, SCHED_FIFO, &sp) != 0)
        printf("note: SCHED_FIFO not permitted (%s): the loop runs at normal priority\n", strerror(errno));
    if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
        printf("note: mlockall not permitted (%s): pages may fault during the loop\n", strerror(errno));

#ifdef CHAIN
    const double kp = 400.0, kv = 40.0, w = 2.0, amp = 0.3;
    double q[NQ], qd[NQ], tau[NQ], M[NQ * NQ], h[NQ], J[6 * NQ], jdqd[6];
    double worst = 0.0;
    for (i = 0; i < NQ; ++i) { q[i] = 0.05; qd[i] = amp * w; }  /* 0.05 rad off the path */
#else
    const styx_high_ct_params params = STYX_HIGH_CT_PARAMS_DEFAULT;
    const double start[3] = {0.0, 0.12, 0.0}, amp[3] = {0.01, 0.01, 0.2}, freq[3] = {0.5, 0.25, 0.3};
    double theta[NQ], theta_dot[NQ], v[NV], tau[NQ], state[NS], state_next[NS], x[3];
    double x_d[3], xd_d[3], xdd_d[3], f_e[3] = {0, 0, 0}, f_i[1] = {0}, vdot[NV], worst = 0.0;
    int status;
    if ((status = styx_high_ct_plant_inverse(start, theta)) != 0) fail("plant_inverse", status, 0);
    for (i = 0; i < NV; ++i) v[i] = 0.0;
    for (i = 0; i < NQ; ++i) theta_dot[i] = tau[i] = 0.0;
    styx_high_ct_servo_init(theta, theta_dot, state);
#endif
    long long next = now_ns() + period;
    for (k = 0; k < cycles; ++k) {
        struct timespec wake = {(time_t)(next / NS_PER_S), (long)(next % NS_PER_S)};
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &wake, NULL) == EINTR) {}
        long long woke = now_ns();
        late[k] = woke - next;
        double t = (double)k * dt;
#ifdef CHAIN
        /* sense (the plant's state), compute, actuate */
        double q_d = amp * sin(w * t), qd_d = amp * w * cos(w * t), qdd_d = -amp * w * w * sin(w * t), acc[NQ];
        int j, status = puma560_servo_terms(q, qd, M, h, J, jdqd);
        if (status != 0) fail("servo_terms", status, k);
        for (i = 0; i < NQ; ++i) acc[i] = qdd_d + kv * (qd_d - qd[i]) + kp * (q_d - q[i]);
        for (i = 0; i < NQ; ++i) {
            tau[i] = h[i];
            for (j = 0; j < NQ; ++j) tau[i] += M[i * NQ + j] * acc[j];
        }
        busy[k] = now_ns() - woke;
        for (i = 0; i < NQ; ++i) if (k > cycles / 2) worst = fmax(worst, fabs(q[i] - q_d));
        plant_step(q, qd, tau, dt, k);
#else
        for (i = 0; i < 3; ++i) {
            double wi = 2.0 * M_PI * freq[i];
            x_d[i] = start[i] + amp[i] * sin(wi * t);
            xd_d[i] = amp[i] * wi * cos(wi * t);
            xdd_d[i] = -amp[i] * wi * wi * sin(wi * t);
        }
        /* sense: the joint rates of the plant's state (theta_dot does not depend on tau) */
        if ((status = styx_high_ct_plant_dynamics(theta, v, tau, theta_dot, vdot)) != 0) fail("plant_dynamics", status, k);
        status = styx_high_ct_servo_step(theta, theta_dot, x_d, xd_d, xdd_d, f_e, f_i, state, &dt, &params, tau,
                                         state_next);
        if (status != 0) fail("servo_step", status, k);
        memcpy(state, state_next, sizeof state);
        busy[k] = now_ns() - woke;
        styx_high_ct_plant_position(theta, x);
        for (i = 0; i < 3; ++i) if (k > cycles / 2) worst = fmax(worst, fabs(x[i] - x_d[i]));
        plant_step(theta, v, tau, dt, k);
#endif
        next += period;
    }
    printf("%ld cycles at %.0f Hz (period %.1f us)\n", cycles, rate, period / 1e3);
    printf("tracking error, second half: max %.3e (rad or m)\n", worst);
    report("period jitter (late)", late, cycles);
    report("servo computation", busy, cycles);
    free(late);
    free(busy);
    return 0;
}
