/* qp_dual.c: a dense QP solver with static memory, Goldfarb and Idnani's dual active-set method (the one of
 * quadprog), for
 *
 *     min 1/2 z' H z + h' z    s.t.  lbx <= z <= ubx,   lba <= A z <= uba
 *
 * with H positive definite (the condensed Gauss-Newton Hessian of the NMPC, the MHE window's). From the
 * unconstrained minimum z = -H^-1 h it adds a violated constraint, takes full or partial steps, and drops
 * constraints whose multiplier would change sign, keeping J = L^-T Q and the triangular R of the active normals up
 * to date by Givens rotations (O(n^2) per change). A bound or a row whose limit is beyond +-QP_BIG is never
 * active. Warm start: the constraint added is the most violated of those active at the last solve's optimum
 * (S.qp_prev), else the most violated of all; any violated choice keeps the method's finite termination and the
 * unique optimum, and a sequence of similar QPs (the NMPC's periods) spares the additions a cold start drops again.
 * A zeroed state (a reset) or a failed solve starts cold.
 *
 * qp_solve(H, h, A, lba, uba, lbx, ubx, z) returns 0 (optimal), 1 (H not positive definite), 2 (infeasible) or 3
 * (more than QP_ITER_LIMIT active-set changes); S.qp_iters holds the active-set changes it took. Expected before it
 * (qp_dual.c.jinja writes them, rendered by cartpole.codegen.qp_source): cp_real, CP_REAL_IS_FLOAT, the sizes
 * QP_NZ and QP_NR, QP_ROWLEN(r) (row r of A is zero from that column on except its last), QP_ITER_LIMIT, and the
 * state struct S with the qp_* work arrays. A second solver in the same program renames qp_/QP_
 * (cartpole.codegen.qp_source's prefix). Maths from <math.h>: sqrt, fabs.
 */
#define QP_NC (2 * QP_NZ + 2 * QP_NR)
#define QP_BIG 1e20
#if CP_REAL_IS_FLOAT
#define QP_TOL 1e-5f
#define QP_ZTOL 1e-6f
#else
#define QP_TOL 1e-6 /* DAQP's primal tolerance: a constraint violated by less is not added */
#define QP_ZTOL 1e-14
#endif

/* constraint i as n_i' z >= b_i: 2j lower bound of z_j, 2j+1 upper, 2 QP_NZ + 2r the row r's lower, +1 its upper */
static int qp_inactive(int i, const cp_real* lba, const cp_real* uba, const cp_real* lbx, const cp_real* ubx)
{
    if (i < 2 * QP_NZ) {
        return i % 2 ? !(ubx[i / 2] < QP_BIG) : !(lbx[i / 2] > -QP_BIG);
    }
    i -= 2 * QP_NZ;
    return i % 2 ? !(uba[i / 2] < QP_BIG) : !(lba[i / 2] > -QP_BIG);
}

/* n_i' v - b_i */
static cp_real qp_slack(int i, const cp_real* v, const cp_real* A, const cp_real* lba, const cp_real* uba,
                        const cp_real* lbx, const cp_real* ubx)
{
    int j, r;
    cp_real acc = 0;
    if (i < 2 * QP_NZ) {
        return i % 2 ? ubx[i / 2] - v[i / 2] : v[i / 2] - lbx[i / 2];
    }
    r = (i - 2 * QP_NZ) / 2;
    for (j = 0; j < QP_ROWLEN(r); ++j) {
        acc += A[r * QP_NZ + j] * v[j];
    }
    acc += A[r * QP_NZ + QP_NZ - 1] * v[QP_NZ - 1];
    return (i % 2) ? uba[r] - acc : acc - lba[r];
}

/* d = J' n_i (qp_J holds J', row k = column k of J) */
static void qp_jtn(int i, const cp_real* A, cp_real* d)
{
    int j, k, r;
    cp_real sg;
    if (i < 2 * QP_NZ) {
        sg = i % 2 ? -1 : 1;
        for (k = 0; k < QP_NZ; ++k) {
            d[k] = sg * S.qp_J[k * QP_NZ + i / 2];
        }
        return;
    }
    r = (i - 2 * QP_NZ) / 2;
    sg = (i % 2) ? -1 : 1;
    for (k = 0; k < QP_NZ; ++k) {
        const cp_real* Jk = S.qp_J + k * QP_NZ;
        cp_real acc = 0;
        for (j = 0; j < QP_ROWLEN(r); ++j) {
            acc += A[r * QP_NZ + j] * Jk[j];
        }
        acc += A[r * QP_NZ + QP_NZ - 1] * Jk[QP_NZ - 1];
        d[k] = sg * acc;
    }
}

/* n_i' v */
static cp_real qp_ndot(int i, const cp_real* A, const cp_real* v)
{
    int j, r;
    cp_real acc = 0;
    if (i < 2 * QP_NZ) {
        return i % 2 ? -v[i / 2] : v[i / 2];
    }
    r = (i - 2 * QP_NZ) / 2;
    for (j = 0; j < QP_ROWLEN(r); ++j) {
        acc += A[r * QP_NZ + j] * v[j];
    }
    acc += A[r * QP_NZ + QP_NZ - 1] * v[QP_NZ - 1];
    return (i % 2) ? -acc : acc;
}

static void qp_givens(cp_real a, cp_real b, cp_real* c, cp_real* s, cp_real* r)
{
    if (b == 0) {
        *c = 1;
        *s = 0;
        *r = a;
        return;
    }
    *r = sqrt(a * a + b * b);
    *c = a / *r;
    *s = b / *r;
}

/* columns a and b of J (rows of J') */
static void qp_rot_cols(int a, int b, cp_real c, cp_real s)
{
    int k;
    cp_real x, y, * Ja = S.qp_J + a * QP_NZ, * Jb = S.qp_J + b * QP_NZ;
    for (k = 0; k < QP_NZ; ++k) {
        x = Ja[k];
        y = Jb[k];
        Ja[k] = c * x + s * y;
        Jb[k] = -s * x + c * y;
    }
}

/* the constraint with J' n = d joins the active set as number q */
static void qp_add(int q)
{
    int k;
    cp_real c, s, r;
    for (k = QP_NZ - 1; k > q; --k) {
        if (S.qp_d[k] == 0) { /* nothing to rotate away (the identity rotation, skipped) */
            continue;
        }
        qp_givens(S.qp_d[k - 1], S.qp_d[k], &c, &s, &r);
        S.qp_d[k - 1] = r;
        S.qp_d[k] = 0;
        qp_rot_cols(k - 1, k, c, s);
    }
    for (k = 0; k <= q; ++k) {
        S.qp_R[k * QP_NZ + q] = S.qp_d[k];
    }
}

/* active constraint l of q leaves */
static void qp_drop(int q, int l)
{
    int i, j;
    cp_real c, s, r, x, y;
    for (i = 0; i < q; ++i) {
        for (j = l; j < q - 1; ++j) {
            S.qp_R[i * QP_NZ + j] = S.qp_R[i * QP_NZ + j + 1];
        }
        S.qp_R[i * QP_NZ + q - 1] = 0;
    }
    for (j = l; j < q - 1; ++j) {
        qp_givens(S.qp_R[j * QP_NZ + j], S.qp_R[(j + 1) * QP_NZ + j], &c, &s, &r);
        for (i = j; i < q - 1; ++i) {
            x = S.qp_R[j * QP_NZ + i];
            y = S.qp_R[(j + 1) * QP_NZ + i];
            S.qp_R[j * QP_NZ + i] = c * x + s * y;
            S.qp_R[(j + 1) * QP_NZ + i] = -s * x + c * y;
        }
        S.qp_R[(j + 1) * QP_NZ + j] = 0;
        qp_rot_cols(j, j + 1, c, s);
    }
    for (i = 0; i < QP_NZ; ++i) {
        S.qp_R[(q - 1) * QP_NZ + i] = 0;
    }
    S.qp_isact[S.qp_act[l]] = 0;
    for (j = l; j < q - 1; ++j) {
        S.qp_act[j] = S.qp_act[j + 1];
        S.qp_u[j] = S.qp_u[j + 1];
    }
}

/* a failed solve (code): the next starts cold; it iterations taken */
static int qp_cold(int it, int code)
{
    int i;
    for (i = 0; i < QP_NC; ++i) {
        S.qp_prev[i] = 0;
    }
    S.qp_iters = it;
    return code;
}

/* H is overwritten by its Cholesky factor. Warm-started: the constraints active at the last solve's optimum are
 * added first while violated (S.qp_prev, cleared by a zeroed state or a failure); S.qp_iters the active-set changes
 * taken. */
static int qp_solve(cp_real* H, const cp_real* h, const cp_real* A, const cp_real* lba, const cp_real* uba,
                    const cp_real* lbx, const cp_real* ubx, cp_real* z)
{
    int i, j, k, q = 0, p, pw, l, it = 0;
    cp_real acc, t1, t2, t, smin, sw, sp, zn, unew, zmax, dmax;
    /* H = L L' (lower, in place) */
    for (j = 0; j < QP_NZ; ++j) {
        acc = H[j * QP_NZ + j];
        for (k = 0; k < j; ++k) {
            acc -= H[j * QP_NZ + k] * H[j * QP_NZ + k];
        }
        if (!(acc > 0)) {
            return qp_cold(0, 1);
        }
        H[j * QP_NZ + j] = sqrt(acc);
        for (i = j + 1; i < QP_NZ; ++i) {
            acc = H[i * QP_NZ + j];
            for (k = 0; k < j; ++k) {
                acc -= H[i * QP_NZ + k] * H[j * QP_NZ + k];
            }
            H[i * QP_NZ + j] = acc / H[j * QP_NZ + j];
        }
    }
    /* J' = L^-1 (row-major), row by row: row i = (e_i - sum_k<i L_ik row k) / L_ii */
    for (i = 0; i < QP_NZ; ++i) {
        cp_real* row = S.qp_J + i * QP_NZ;
        for (j = 0; j < QP_NZ; ++j) {
            row[j] = i == j ? 1 : 0;
        }
        for (k = 0; k < i; ++k) {
            const cp_real* rk = S.qp_J + k * QP_NZ;
            cp_real lik = H[i * QP_NZ + k];
            for (j = 0; j <= k; ++j) {
                row[j] -= lik * rk[j];
            }
        }
        for (j = 0; j <= i; ++j) {
            row[j] /= H[i * QP_NZ + i];
        }
    }
    for (i = 0; i < QP_NC; ++i) {
        S.qp_isact[i] = 0;
    }
    for (i = 0; i < QP_NZ * QP_NZ; ++i) {
        S.qp_R[i] = 0;
    }
    for (k = 0; k < QP_NZ; ++k) { /* z = -J J' h */
        acc = 0;
        for (j = 0; j < QP_NZ; ++j) {
            acc += S.qp_J[k * QP_NZ + j] * h[j];
        }
        S.qp_d[k] = acc;
    }
    for (i = 0; i < QP_NZ; ++i) {
        z[i] = 0;
    }
    for (k = 0; k < QP_NZ; ++k) {
        for (i = 0; i < QP_NZ; ++i) {
            z[i] -= S.qp_J[k * QP_NZ + i] * S.qp_d[k];
        }
    }
    for (;;) {
        /* the constraint to add: the most violated of those active at the last solve's optimum (the warm start),
         * else the most violated of all; any violated constraint keeps the method's finite termination and its
         * unique optimum, the previous active set saves the additions that would be dropped again */
        p = -1;
        smin = 0;
        for (i = 0; i < QP_NC; ++i) { /* the last optimum's constraints: only they are scanned while one is violated */
            cp_real si;
            if (!S.qp_prev[i] || S.qp_isact[i] || qp_inactive(i, lba, uba, lbx, ubx)) {
                continue;
            }
            si = qp_slack(i, z, A, lba, uba, lbx, ubx);
            if (si < -QP_TOL && (p < 0 || si < smin)) {
                smin = si;
                p = i;
            }
        }
        if (p < 0) { /* none violated: the most violated of all */
            pw = -1;
            sw = 0;
            for (i = 0; i < QP_NC; ++i) {
                cp_real si;
                if (S.qp_isact[i] || qp_inactive(i, lba, uba, lbx, ubx)) {
                    continue;
                }
                si = qp_slack(i, z, A, lba, uba, lbx, ubx);
                if (pw < 0 || si < sw) {
                    sw = si;
                    pw = i;
                }
            }
            p = pw;
            smin = sw;
        }
        if (p < 0 || !(smin < -QP_TOL)) {
            for (i = 0; i < QP_NC; ++i) { /* the warm start of the next solve */
                S.qp_prev[i] = S.qp_isact[i];
            }
            S.qp_iters = it;
            return 0;
        }
        unew = 0;
        for (;;) {
            if (++it > QP_ITER_LIMIT) {
                return qp_cold(it, 3);
            }
            qp_jtn(p, A, S.qp_d);
            zmax = 0;
            dmax = 1;
            for (i = 0; i < QP_NZ; ++i) {
                S.qp_zd[i] = 0;
            }
            for (k = q; k < QP_NZ; ++k) { /* zd = J[:, q:] d[q:] */
                const cp_real* Jk = S.qp_J + k * QP_NZ;
                cp_real dk = S.qp_d[k];
                for (i = 0; i < QP_NZ; ++i) {
                    S.qp_zd[i] += Jk[i] * dk;
                }
            }
            for (i = 0; i < QP_NZ; ++i) {
                zmax = fabs(S.qp_zd[i]) > zmax ? fabs(S.qp_zd[i]) : zmax;
                dmax = fabs(S.qp_d[i]) > dmax ? fabs(S.qp_d[i]) : dmax;
            }
            for (i = q - 1; i >= 0; --i) { /* R r = d[:q] */
                acc = S.qp_d[i];
                for (k = i + 1; k < q; ++k) {
                    acc -= S.qp_R[i * QP_NZ + k] * S.qp_r[k];
                }
                S.qp_r[i] = acc / S.qp_R[i * QP_NZ + i];
            }
            t1 = 0;
            l = -1;
            for (j = 0; j < q; ++j) {
                if (S.qp_r[j] > 0 && (l < 0 || S.qp_u[j] / S.qp_r[j] < t1)) {
                    t1 = S.qp_u[j] / S.qp_r[j];
                    l = j;
                }
            }
            zn = qp_ndot(p, A, S.qp_zd);
            sp = qp_slack(p, z, A, lba, uba, lbx, ubx);
            if (zmax > QP_ZTOL * dmax && zn > 0) {
                t2 = -sp / zn;
                t = (l >= 0 && t1 < t2) ? t1 : t2;
            } else if (l >= 0) {
                t2 = -1;
                t = t1;
            } else {
                return qp_cold(it, 2);
            }
            if (t2 >= 0) {
                for (i = 0; i < QP_NZ; ++i) {
                    z[i] += t * S.qp_zd[i];
                }
            }
            for (j = 0; j < q; ++j) {
                S.qp_u[j] -= t * S.qp_r[j];
            }
            unew += t;
            if (t2 >= 0 && !(l >= 0 && t1 < t2)) {
                qp_add(q);
                S.qp_act[q] = p;
                S.qp_isact[p] = 1;
                S.qp_u[q] = unew;
                ++q;
                break;
            }
            qp_drop(q, l);
            --q;
        }
    }
}
