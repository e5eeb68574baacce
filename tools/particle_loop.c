/* A plain C baseline of the offline closed loop, for tools/bench_particles.py: the report's backstepping law with
 * constant-rate adaptation (ERRATA 2 and 3) flying the 6-DOF plant (Eqs. 2.1-2.7) by RK4, with the tuning cost,
 * the saturation cut-off and the divergence check of rov_mav/offline/loop_kernel.py:simulate_batch.
 *
 * The same equations as rov_mav/model/kernel.py and rov_mav/control/backstepping.py, written again in C; the
 * measurement is the true state (no sensor noise, telemetry every tick). The packed-array offsets and the limits
 * (P_*, E_*, MAX_TILT, MAX_SPEED, DIVERGED_COST) come from the Python modules as -D definitions at compile time.
 */
#include <math.h>

#define PI 3.14159265358979323846

static void rotation(double cphi, double sphi, double cth, double sth, double cpsi, double spsi, double R[9])
{
    R[0] = cpsi * cth;  R[1] = -spsi * cphi + cpsi * sth * sphi;  R[2] = spsi * sphi + cpsi * cphi * sth;
    R[3] = spsi * cth;  R[4] = cpsi * cphi + sphi * sth * spsi;   R[5] = -cpsi * sphi + sth * spsi * cphi;
    R[6] = -sth;        R[7] = cth * sphi;                        R[8] = cth * cphi;
}

static double mass_row(const double *m, int row, const double v[6])
{
    const double *M = m + P_M + 6 * row;
    return M[0] * v[0] + M[1] * v[1] + M[2] * v[2] + M[3] * v[3] + M[4] * v[4] + M[5] * v[5];
}

/* C(nu) nu, C from M by the m2c construction: [[0, -S(a)], [-S(a), -S(b)]], a = M[0:3] nu, b = M[3:6] nu. */
static void coriolis(const double *m, const double nu[6], double c[6])
{
    double a0 = mass_row(m, 0, nu), a1 = mass_row(m, 1, nu), a2 = mass_row(m, 2, nu);
    double b0 = mass_row(m, 3, nu), b1 = mass_row(m, 4, nu), b2 = mass_row(m, 5, nu);
    double u = nu[0], v = nu[1], w = nu[2], p = nu[3], q = nu[4], r = nu[5];
    c[0] = -(a1 * r - a2 * q);
    c[1] = -(a2 * p - a0 * r);
    c[2] = -(a0 * q - a1 * p);
    c[3] = -(a1 * w - a2 * v) - (b1 * r - b2 * q);
    c[4] = -(a2 * u - a0 * w) - (b2 * p - b0 * r);
    c[5] = -(a0 * v - a1 * u) - (b0 * q - b1 * p);
}

static void damping(const double *m, const double nu[6], double d[6])
{
    for (int i = 0; i < 6; i++)
        d[i] = (m[P_DLIN + i] + m[P_DQUAD + i] * fabs(nu[i])) * nu[i];
}

static void restoring(const double *m, double cphi, double sphi, double cth, double sth, double g[6])
{
    double W = m[P_W], B = m[P_B], net = W - B;
    double gx = m[P_RG] * W - m[P_RB] * B;
    double gy = m[P_RG + 1] * W - m[P_RB + 1] * B;
    double gz = m[P_RG + 2] * W - m[P_RB + 2] * B;
    g[0] = net * sth;
    g[1] = -net * cth * sphi;
    g[2] = -net * cth * cphi;
    g[3] = -gy * cth * cphi + gz * cth * sphi;
    g[4] = gz * sth + gx * cth * cphi;
    g[5] = -gx * cth * sphi - gy * sth;
}

/* d/dt [eta; nu]: eta_dot = J(eta) nu; M nu_dot = tau - C(nu) nu - D(nu_r) nu_r - g(eta), nu_r relative to the
 * NED current. */
static void derivative(const double *m, const double x[12], const double tau[6], const double *current,
                       double dx[12])
{
    double cphi = cos(x[3]), sphi = sin(x[3]), cth = cos(x[4]), sth = sin(x[4]), cpsi = cos(x[5]), spsi = sin(x[5]);
    const double *nu = x + 6;
    double R[9], c[6], d[6], g[6], rel[6], f[6];
    rotation(cphi, sphi, cth, sth, cpsi, spsi, R);
    for (int i = 0; i < 3; i++)
        dx[i] = R[3 * i] * nu[0] + R[3 * i + 1] * nu[1] + R[3 * i + 2] * nu[2];
    double p = nu[3], q = nu[4], r = nu[5];
    dx[3] = p + (sphi * q + cphi * r) * sth / cth;
    dx[4] = cphi * q - sphi * r;
    dx[5] = (sphi * q + cphi * r) / cth;
    for (int i = 0; i < 3; i++) {
        rel[i] = nu[i] - (R[i] * current[0] + R[3 + i] * current[1] + R[6 + i] * current[2]);
        rel[3 + i] = nu[3 + i];
    }
    coriolis(m, nu, c);
    damping(m, rel, d);
    restoring(m, cphi, sphi, cth, sth, g);
    for (int i = 0; i < 6; i++)
        f[i] = tau[i] - c[i] - d[i] - g[i];
    for (int i = 0; i < 6; i++) {
        const double *row = m + P_MINV + 6 * i;
        dx[6 + i] = row[0] * f[0] + row[1] * f[1] + row[2] * f[2] + row[3] * f[3] + row[4] * f[4] + row[5] * f[5];
    }
}

/* tau plus the disturbance at time t: a constant and a sinusoid per DOF. */
static void disturbed(const double *env, double t, const double tau[6], double out[6])
{
    double period = env[E_PERIOD];
    double phase = period > 0.0 ? sin(2.0 * PI * t / period) : 0.0;
    for (int i = 0; i < 6; i++)
        out[i] = tau[i] + env[E_DIST + i] + env[E_AMP + i] * phase;
}

static void rk4(const double *m, const double *env, double x[12], const double tau[6], double t, double h)
{
    double k1[12], k2[12], k3[12], k4[12], xs[12], total[6];
    const double *current = env + E_CURRENT;
    disturbed(env, t, tau, total);
    derivative(m, x, total, current, k1);
    disturbed(env, t + 0.5 * h, tau, total);
    for (int i = 0; i < 12; i++) xs[i] = x[i] + 0.5 * h * k1[i];
    derivative(m, xs, total, current, k2);
    for (int i = 0; i < 12; i++) xs[i] = x[i] + 0.5 * h * k2[i];
    derivative(m, xs, total, current, k3);
    disturbed(env, t + h, tau, total);
    for (int i = 0; i < 12; i++) xs[i] = x[i] + h * k3[i];
    derivative(m, xs, total, current, k4);
    for (int i = 0; i < 12; i++) x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
}

static double wrap(double a)
{
    double r = fmod(a + PI, 2.0 * PI);
    if (r < 0.0) r += 2.0 * PI;
    return r - PI;
}

/* The backstepping law and the adaptation direction: tau = M J^-1 (eta_dd_d - k1 e_dot - J_dot nu - k2 s)
 * + C nu + D nu + g - tau_hat, s = e_dot + k1 e, grad = M^-T J^T s. */
static void law(const double *m, const double *k1, const double *k2, const double x[12], const double *ref,
                const double tau_hat[6], double tau[6], double s[6], double grad[6])
{
    double cphi = cos(x[3]), sphi = sin(x[3]), cth = cos(x[4]), sth = sin(x[4]), cpsi = cos(x[5]), spsi = sin(x[5]);
    const double *nu = x + 6;
    double u = nu[0], v = nu[1], w = nu[2], p = nu[3], q = nu[4], r = nu[5];
    double R[9], eta_dot[6], A[6], a[6], wv[6], c[6], d[6], g[6];
    rotation(cphi, sphi, cth, sth, cpsi, spsi, R);
    for (int i = 0; i < 3; i++)
        eta_dot[i] = R[3 * i] * u + R[3 * i + 1] * v + R[3 * i + 2] * w;
    double dphi = p + (sphi * q + cphi * r) * sth / cth, dth = cphi * q - sphi * r, dpsi = (sphi * q + cphi * r) / cth;
    eta_dot[3] = dphi; eta_dot[4] = dth; eta_dot[5] = dpsi;
    /* J_dot nu: R (omega x nu1) and T_dot nu2 */
    double cx = q * w - r * v, cy = r * u - p * w, cz = p * v - q * u, tth = sth / cth, sec2 = 1.0 / (cth * cth);
    for (int i = 0; i < 3; i++)
        A[i] = R[3 * i] * cx + R[3 * i + 1] * cy + R[3 * i + 2] * cz;
    A[3] = dphi * (cphi * tth * q - sphi * tth * r) + dth * sec2 * (sphi * q + cphi * r);
    A[4] = dphi * (-sphi * q - cphi * r);
    A[5] = dphi * (cphi * q - sphi * r) / cth + dth * sth * sec2 * (sphi * q + cphi * r);
    for (int i = 0; i < 6; i++) {
        double e = x[i] - ref[i];
        if (i >= 3) e = wrap(e);
        double e_dot = eta_dot[i] - ref[6 + i];
        s[i] = e_dot + k1[i] * e;
        a[i] = ref[12 + i] - k1[i] * e_dot - A[i] - k2[i] * s[i];
    }
    wv[0] = R[0] * a[0] + R[3] * a[1] + R[6] * a[2];
    wv[1] = R[1] * a[0] + R[4] * a[1] + R[7] * a[2];
    wv[2] = R[2] * a[0] + R[5] * a[1] + R[8] * a[2];
    wv[3] = a[3] - sth * a[5];
    wv[4] = cphi * a[4] + cth * sphi * a[5];
    wv[5] = -sphi * a[4] + cth * cphi * a[5];
    coriolis(m, nu, c);
    damping(m, nu, d);
    restoring(m, cphi, sphi, cth, sth, g);
    for (int i = 0; i < 6; i++)
        tau[i] = mass_row(m, i, wv) + c[i] + d[i] + g[i] - tau_hat[i];
    double j[6];
    j[0] = R[0] * s[0] + R[3] * s[1] + R[6] * s[2];
    j[1] = R[1] * s[0] + R[4] * s[1] + R[7] * s[2];
    j[2] = R[2] * s[0] + R[5] * s[1] + R[8] * s[2];
    j[3] = s[3];
    j[4] = sphi * tth * s[3] + cphi * s[4] + sphi / cth * s[5];
    j[5] = cphi * tth * s[3] - sphi * s[4] + cphi / cth * s[5];
    for (int i = 0; i < 6; i++) {
        const double *col = m + P_MINV + i;
        grad[i] = col[0] * j[0] + col[6] * j[1] + col[12] * j[2] + col[18] * j[3] + col[24] * j[4] + col[30] * j[5];
    }
}

static int diverged(const double x[12])
{
    for (int i = 0; i < 12; i++)
        if (!isfinite(x[i])) return 1;
    if (fabs(x[3]) > MAX_TILT || fabs(x[4]) > MAX_TILT) return 1;
    for (int i = 6; i < 12; i++)
        if (fabs(x[i]) > MAX_SPEED) return 1;
    return 0;
}

/* Each run b: params[b] = [k1 | k2 | gamma | d_max] (24,); ref (n_steps + 1, 18); weights (3, 6) = [Q; Q_e; R];
 * tau_ff (n_steps + 1, 6). Writes cost[b], steps_done[b] and the final state x_end[b] (12,). */
void run_batch(long n_runs, long n_steps, const double *plant, const double *env, const double *ctrl,
               const double *params, const double *ref, double dt, long substeps, const double *x0,
               const double *weights, const double *tau_ff, const double *tau_max, const double *tau_limit,
               double *cost, long *steps_done, double *x_end)
{
    double h = dt / substeps;
    for (long b = 0; b < n_runs; b++) {
        const double *pm = plant + b * P_SIZE, *pe = env + b * E_SIZE, *par = params + b * 24;
        const double *k1 = par, *k2 = par + 6, *gamma = par + 12, *d_max = par + 18;
        double x[12], tau_hat[6] = {0}, tau[6], s[6], grad[6], applied[6], total = 0.0;
        long done = n_steps;
        for (int i = 0; i < 12; i++) x[i] = x0[i];
        for (long k = 0; k <= n_steps; k++) {
            const double *rk = ref + 18 * k;
            law(ctrl, k1, k2, x, rk, tau_hat, tau, s, grad);
            for (int i = 0; i < 6; i++) {
                double value = tau_hat[i] + dt * gamma[i] * grad[i];
                tau_hat[i] = fmin(fmax(value, -d_max[i]), d_max[i]);
            }
            if (k == n_steps) break;
            int saturated = 0;
            for (int i = 0; i < 6; i++)
                if (fabs(tau[i]) > tau_max[i]) saturated = 1;
            if (saturated) { done = k; total = DIVERGED_COST; break; }
            double running = 0.0;
            for (int i = 0; i < 6; i++) {
                double uu = tau[i] - tau_ff[6 * k + i];
                running += weights[i] * s[i] * s[i] + weights[12 + i] * uu * uu;
                if (weights[6 + i] != 0.0) {
                    double e = x[i] - rk[i];
                    if (i >= 3) e = wrap(e);
                    running += weights[6 + i] * e * e;
                }
            }
            total += running * dt;
            for (int i = 0; i < 6; i++) applied[i] = fmin(fmax(tau[i], -tau_limit[i]), tau_limit[i]);
            for (long j = 0; j < substeps; j++) rk4(pm, pe, x, applied, k * dt + j * h, h);
            if (diverged(x)) { done = k; total = DIVERGED_COST; break; }
        }
        cost[b] = total;
        steps_done[b] = done;
        for (int i = 0; i < 12; i++) x_end[12 * b + i] = x[i];
    }
}
