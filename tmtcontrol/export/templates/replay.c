/* replay.c - run the exported controller over recorded measurements.
 *
 *   ./replay MEASUREMENTS.csv COMMANDS.csv   one tmt_step per row, from tmt_init()
 *   ./replay --bench N [MEASUREMENTS.csv]    per-call time of tmt_step over N calls
 *
 * MEASUREMENTS.csv: a header line, then one row per period with the columns
 *   t,@MEAS_COLUMNS@
 * (t in s, then tmt_measurement's fields in order; units and frames in README.md).
 * COMMANDS.csv, a new file (an existing one is never overwritten: exit 2), gets
 * t and tmt_command's fields:
 *   t,@CMD_COLUMNS@
 * The benchmark cycles through the rows of MEASUREMENTS.csv (or repeats the
 * initial state's zero measurement) and prints the median, 99.9th percentile
 * and maximum of the per-call time (CLOCK_MONOTONIC around each call).
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "tmt_controller.h"

#define MAX_LINE 8192
#define MEAS_HEADER "t,@MEAS_COLUMNS@"

static int parse_row(char *line, double *t, double *v)
{
    char *p = line, *end;
    int i;
    *t = strtod(p, &end);
    if (end == p) {
        return -1;
    }
    p = end;
    for (i = 0; i < TMT_N_MEASUREMENT; ++i) {
        if (*p != ',') {
            return -1;
        }
        ++p;
        v[i] = strtod(p, &end);
        if (end == p) {
            return -1;
        }
        p = end;
    }
    while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n') {    /* CRLF, trailing blanks */
        ++p;
    }
    return *p == '\0' ? 0 : -1;     /* an extra column is an error, not ignored */
}

/* The header must name the columns in replay's order (a reordered or
 * different table would otherwise be read silently into the wrong fields). */
static int header_ok(char *line)
{
    size_t n = strlen(line);
    while (n > 0 && (line[n - 1] == '\n' || line[n - 1] == '\r' || line[n - 1] == ' ')) {
        line[--n] = '\0';
    }
    return strcmp(line, MEAS_HEADER) == 0;
}

static void set_measurement(tmt_measurement *meas, const double *v)
{
@READ_MEAS@
}

/* Writes one row; 0, or -1 if the stream has failed (a full disk, a file size limit). */
static int write_command(FILE *out, double t, const tmt_command *cmd)
{
    fprintf(out, "%.17g", t);
@WRITE_CMD@
    fputc('\n', out);
    return ferror(out) ? -1 : 0;
}

/* A write that failed: one line, the partial file removed (never left as if complete). */
static int write_failed(FILE *out, const char *path, long rows, double *data, double *times)
{
    int err = errno;
    fclose(out);
    remove(path);
    free(data);
    free(times);
    fprintf(stderr, "replay: writing %s failed after %ld row(s) (%s); the partial file was removed\n", path,
            rows, err ? strerror(err) : "write error");
    return 3;
}

/* Reads the rows of path into *rows and *times; returns their number, or -1
 * after printing one line saying why (the arrays are then freed). */
static long read_all(const char *path, double **rows, double **times)
{
    FILE *in = fopen(path, "r");
    char line[MAX_LINE];
    long n = 0, cap = 1024;
    double *r, *t;
    *rows = malloc(sizeof(double) * TMT_N_MEASUREMENT * cap);
    *times = malloc(sizeof(double) * cap);
    if (in == NULL || *rows == NULL || *times == NULL) {
        fprintf(stderr, "replay: cannot read measurements from %s\n", path);
        goto fail;
    }
    if (fgets(line, sizeof line, in) == NULL) {
        fprintf(stderr, "replay: %s: empty file (expected the header line %s)\n", path, MEAS_HEADER);
        goto fail;
    }
    if (!header_ok(line)) {
        fprintf(stderr, "replay: %s: row 1: expected the header line %s\n", path, MEAS_HEADER);
        goto fail;
    }
    while (fgets(line, sizeof line, in) != NULL) {
        if (n == cap) {
            cap *= 2;
            r = realloc(*rows, sizeof(double) * TMT_N_MEASUREMENT * cap);
            if (r != NULL) {
                *rows = r;
            }
            t = realloc(*times, sizeof(double) * cap);
            if (t != NULL) {
                *times = t;
            }
            if (r == NULL || t == NULL) {
                fprintf(stderr, "replay: %s: out of memory at row %ld\n", path, n + 2);
                goto fail;
            }
        }
        if (parse_row(line, *times + n, *rows + n * TMT_N_MEASUREMENT) != 0) {
            fprintf(stderr, "replay: %s: row %ld: expected t and %d numbers separated by commas\n", path,
                    n + 2, TMT_N_MEASUREMENT);
            goto fail;
        }
        ++n;
    }
    if (n == 0) {
        fprintf(stderr, "replay: %s: no measurement rows after the header\n", path);
        goto fail;
    }
    fclose(in);
    return n;
fail:
    if (in != NULL) {
        fclose(in);
    }
    free(*rows);
    free(*times);
    *rows = NULL;
    *times = NULL;
    return -1;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static int bench(long calls, const char *path)
{
    static tmt_params params;
    static tmt_state state;
    static tmt_measurement meas;
    static tmt_command cmd;
    double *rows = NULL, *times = NULL, *dt, sink = 0.0;
    long nrows = 0, k, refused = 0;
    int rc;
    struct timespec a, b;

    if (path != NULL && (nrows = read_all(path, &rows, &times)) <= 0) {
        return 2;
    }
    dt = malloc(sizeof(double) * (size_t)calls);
    if (dt == NULL) {
        fprintf(stderr, "replay: --bench: cannot allocate the times of %ld calls\n", calls);
        free(rows);
        free(times);
        return 2;
    }
    tmt_default_params(&params);
    tmt_init(&params, &state);
    memset(&meas, 0, sizeof meas);
    for (k = 0; k < calls; ++k) {
        if (nrows > 0) {
            if (k % nrows == 0) {
                tmt_init(&params, &state);
            }
            set_measurement(&meas, rows + (k % nrows) * TMT_N_MEASUREMENT);
        }
        clock_gettime(CLOCK_MONOTONIC, &a);
        rc = tmt_step(&params, &state, &meas, &cmd);
        clock_gettime(CLOCK_MONOTONIC, &b);
        dt[k] = (double)(b.tv_sec - a.tv_sec) * 1e6 + (double)(b.tv_nsec - a.tv_nsec) * 1e-3;
        sink += cmd.x_c[0];
        refused += rc != 0;
    }
    qsort(dt, (size_t)calls, sizeof(double), cmp_double);
    printf("tmt_step: %ld calls, median %.3f us, 99.9%% %.3f us, max %.3f us (inner loop: %s)\n", calls,
           dt[calls / 2], dt[(long)(0.999 * (double)(calls - 1))], dt[calls - 1], TMT_INNER_LOOP ? "yes" : "no");
    free(dt);
    free(rows);
    free(times);
    if (refused > 0) {      /* a refused call returns early: its time is not the law's */
        fflush(stdout);     /* the line it refers to first, also into a file or a pipe */
        fprintf(stderr, "replay: --bench: %ld of %ld calls returned an error (a measurement the controller refuses%s): "
                "the times above are not the law's\n", refused, calls,
                nrows > 0 ? "" : "; without MEAS.csv every measurement is zero: give a logged one");
        return 1;
    }
    return sink != sink;    /* keeps the calls from being optimised away; 0 unless NaN */
}

int main(int argc, char **argv)
{
    static tmt_params params;
    static tmt_state state;
    static tmt_measurement meas;
    static tmt_command cmd;
    double *rows = NULL, *times = NULL;
    long n, k;
    int rc;
    FILE *out;

    if (argc >= 3 && strcmp(argv[1], "--bench") == 0) {
        char *end;
        long calls = strtol(argv[2], &end, 10);
        if (calls < 1 || end == argv[2] || *end != '\0') {
            fprintf(stderr, "replay: --bench: expected a number of calls >= 1, got %s\n", argv[2]);
            return 2;
        }
        return bench(calls, argc > 3 ? argv[3] : NULL);
    }
    if (argc != 3) {
        fprintf(stderr, "usage: %s MEASUREMENTS.csv COMMANDS.csv | --bench N [MEASUREMENTS.csv]\n", argv[0]);
        return 2;
    }
    n = read_all(argv[1], &rows, &times);
    if (n < 0) {
        return 2;
    }
    {   /* a new file only: a recorded log, or any file of the user's, is never overwritten */
        int fd = open(argv[2], O_WRONLY | O_CREAT | O_EXCL, 0644);
        if (fd < 0 && errno == EEXIST) {
            fprintf(stderr, "replay: %s exists; replay writes a new file only (name another one)\n", argv[2]);
        } else if (fd < 0) {
            fprintf(stderr, "replay: cannot write %s\n", argv[2]);
        }
        out = fd < 0 ? NULL : fdopen(fd, "w");
    }
    if (out == NULL) {
        free(rows);
        free(times);
        return 2;
    }
    errno = 0;
    fprintf(out, "t,@CMD_COLUMNS@\n");
    if (ferror(out)) {
        return write_failed(out, argv[2], 0, rows, times);
    }
    tmt_default_params(&params);
    tmt_init(&params, &state);
    for (k = 0; k < n; ++k) {
        set_measurement(&meas, rows + k * TMT_N_MEASUREMENT);
        if ((rc = tmt_step(&params, &state, &meas, &cmd)) != 0) {
            fprintf(stderr, "replay: %s: row %ld: tmt_step returned %d%s\n", argv[1], k + 2, rc,
                    rc == TMT_E_NONFINITE ? " (a non-finite result: check the measurement)" :
                    rc == TMT_E_RANGE ? " (a parameter outside its valid range)" : "");
            fclose(out);
            free(rows);
            free(times);
            return 1;
        }
        if (write_command(out, times[k], &cmd) != 0) {
            return write_failed(out, argv[2], k, rows, times);
        }
    }
    if (fflush(out) != 0 || ferror(out)) {
        return write_failed(out, argv[2], n, rows, times);
    }
    if (fclose(out) != 0) {
        int err = errno;
        remove(argv[2]);
        free(rows);
        free(times);
        fprintf(stderr, "replay: closing %s failed (%s); the partial file was removed\n", argv[2], strerror(err));
        return 3;
    }
    free(rows);
    free(times);
    return 0;
}
