/* Times MuJoCo's mj_step on one model: `steps MODEL INTEGRATOR DT STEPS REPEATS STATE_FILE`.
 *
 * INTEGRATOR is rk4 or euler (MuJoCo's "Euler" is semi-implicit: v' = v + h a, q' = q (+) h v').
 * STATE_FILE holds nq positions then nv velocities (MuJoCo's order and conventions), whitespace
 * separated. Contact, joint limits, the constraint solver, friction loss, springs, dampers and sensors are
 * disabled, so the step integrates rigid-body forward dynamics under gravity alone.
 *
 * One untimed run of STEPS steps from the state (its end state is printed), then REPEATS timed
 * runs from the same state, nothing written on the way; prints one JSON line:
 * {"ns_per_step": median, "nq", "nv", "qpos": [...], "qvel": [...]}. */
#include <mujoco/mujoco.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static void die(const char *what, const char *detail) {
    fprintf(stderr, "steps: %s%s\n", what, detail ? detail : "");
    exit(1);
}

static double now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e9 + (double)t.tv_nsec;
}

static int compare(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Resets the data to the initial state and runs `steps` steps; returns ns per step. */
static double run(const mjModel *m, mjData *d, const mjtNum *qpos0, const mjtNum *qvel0,
                  long steps) {
    mj_resetData(m, d);
    memcpy(d->qpos, qpos0, sizeof(mjtNum) * m->nq);
    memcpy(d->qvel, qvel0, sizeof(mjtNum) * m->nv);
    double start = now_ns();
    for (long i = 0; i < steps; i++) mj_step(m, d);
    return (now_ns() - start) / (double)steps;
}

static void print_array(const char *key, const mjtNum *x, int n) {
    printf("\"%s\": [", key);
    for (int i = 0; i < n; i++) printf("%s%.17g", i ? ", " : "", x[i]);
    printf("]");
}

int main(int argc, char **argv) {
    if (argc != 7) die("usage: steps MODEL rk4|euler DT STEPS REPEATS STATE_FILE", NULL);
    char error[1000] = "";
    mjModel *m = mj_loadXML(argv[1], NULL, error, sizeof(error));
    if (!m) die("cannot load the model: ", error);
    if (!strcmp(argv[2], "rk4")) m->opt.integrator = mjINT_RK4;
    else if (!strcmp(argv[2], "euler")) m->opt.integrator = mjINT_EULER;
    else die("unknown integrator ", argv[2]);
    m->opt.timestep = atof(argv[3]);
    long steps = atol(argv[4]);
    int repeats = atoi(argv[5]);
    if (!(m->opt.timestep > 0) || steps < 1 || repeats < 1) die("bad DT, STEPS or REPEATS", NULL);
    m->opt.disableflags |= mjDSBL_CONTACT | mjDSBL_LIMIT | mjDSBL_CONSTRAINT | mjDSBL_FRICTIONLOSS
                           | mjDSBL_SPRING | mjDSBL_DAMPER | mjDSBL_EQUALITY | mjDSBL_ACTUATION
                           | mjDSBL_SENSOR | mjDSBL_AUTORESET;

    mjtNum *qpos0 = malloc(sizeof(mjtNum) * m->nq), *qvel0 = malloc(sizeof(mjtNum) * m->nv);
    FILE *f = fopen(argv[6], "r");
    if (!f) die("cannot open ", argv[6]);
    for (int i = 0; i < m->nq; i++)
        if (fscanf(f, "%lf", &qpos0[i]) != 1) die("too few positions in ", argv[6]);
    for (int i = 0; i < m->nv; i++)
        if (fscanf(f, "%lf", &qvel0[i]) != 1) die("too few velocities in ", argv[6]);
    fclose(f);

    mjData *d = mj_makeData(m);
    run(m, d, qpos0, qvel0, steps);
    for (int i = 0; i < m->nq + m->nv; i++) {
        mjtNum x = i < m->nq ? d->qpos[i] : d->qvel[i - m->nq];
        if (x != x) die("the run produced NaN", NULL);
    }
    printf("{\"nq\": %ld, \"nv\": %ld, ", (long)m->nq, (long)m->nv);
    print_array("qpos", d->qpos, m->nq);
    printf(", ");
    print_array("qvel", d->qvel, m->nv);

    double *ns = malloc(sizeof(double) * repeats);
    for (int r = 0; r < repeats; r++) ns[r] = run(m, d, qpos0, qvel0, steps);
    qsort(ns, repeats, sizeof(double), compare);
    printf(", \"ns_per_step\": %.1f, \"version\": \"%s\"}\n", ns[repeats / 2], mj_versionString());

    free(ns);
    free(qpos0);
    free(qvel0);
    mj_deleteData(d);
    mj_deleteModel(m);
    return 0;
}
