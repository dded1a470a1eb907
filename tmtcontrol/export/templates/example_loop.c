/* example_loop.c - a fixed-rate control loop skeleton around tmt_step().
 *
 * Replace read_robot() and write_robot() with your robot's interface (a vendor
 * SDK, a fieldbus, ros2_control's read()/write()). The loop waits for absolute
 * deadlines with clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME), so the rate
 * does not drift, and counts overruns (a period whose work ended after the
 * next deadline: that deadline is skipped, not caught up). For hard real time
 * run it under SCHED_FIFO with locked memory (mlockall) on an isolated core.
 *
 * usage: ./example_loop [periods]     (default: 1000 periods of params.Ts)
 */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "tmt_controller.h"

/* The robot stands still at the controller's initial state in this skeleton. */
static int read_robot(tmt_measurement *meas)
{
    (void)meas;      /* fill q, dq (encoders), force (F/T sensor, base frame), the tangential path */
    return 0;
}

static int write_robot(const tmt_command *cmd)
{
    (void)cmd;       /* send q_c (position-controlled robot) or tau (torque interface) */
    return 0;
}

static void add_ns(struct timespec *t, long ns)
{
    t->tv_nsec += ns;
    while (t->tv_nsec >= 1000000000L) {
        t->tv_nsec -= 1000000000L;
        t->tv_sec += 1;
    }
}

static int later(const struct timespec *a, const struct timespec *b)
{
    return a->tv_sec > b->tv_sec || (a->tv_sec == b->tv_sec && a->tv_nsec > b->tv_nsec);
}

int main(int argc, char **argv)
{
    static tmt_params params;    /* static: no large objects on the stack */
    static tmt_state state;
    static tmt_measurement meas;
    static tmt_command cmd;
    long periods = argc > 1 ? strtol(argv[1], NULL, 10) : 1000;
    long period_ns;
    long k, overruns = 0, failures = 0;
    struct timespec next, now;

    tmt_default_params(&params);@EXAMPLE_START@
    /* the period the controller is discretised with: params.Ts, not the exported TMT_TS (edited with it) */
    period_ns = (long)(params.Ts * 1e9 + 0.5);
    tmt_init(&params, &state);
    clock_gettime(CLOCK_MONOTONIC, &next);
    for (k = 0; k < periods; ++k) {
        if (read_robot(&meas) != 0 || tmt_step(&params, &state, &meas, &cmd) != 0 || write_robot(&cmd) != 0) {
            ++failures;     /* on a robot: stop safely here */
        }
        add_ns(&next, period_ns);
        clock_gettime(CLOCK_MONOTONIC, &now);
        if (later(&now, &next)) {
            ++overruns;
            next = now;
        }
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL);
    }
    printf("%ld periods of %ld ns, %ld overruns, %ld failures\n", periods, period_ns, overruns, failures);
    return failures != 0;
}
