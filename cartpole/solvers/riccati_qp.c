/* The SQP's stage-structured QP solved by Riccati recursions and a primal-dual active set (see riccati_qp.py).

   Stages k = 0..N-1: state s_k (nz), control w_k (nu), dynamics s_k+1 = A_k s_k + B_k w_k + c_k with
   [A_k B_k] = T_k (nz x ny, row-major), c_k = (ct_k, 0); cost sum_k 1/2 y_k' Hy_k y_k + gy_k' y_k, y_k = (s_k, w_k).
   s_0 = (0, p_0, du_0): the last RQP_NP states p_0 and du_0 are free (bounded) variables, the others zero. Bounds
   on the knots dz_k = s_k (k >= 1) and du_0:
   the input entries of knot k >= 1 are w_k-1 (eliminated from the recursion when active), the state entries rows
   whose multipliers enter the recursion as linear terms (their responses superposed). */
#include <math.h>
#include <string.h>

/* The sizes are compile-time constants (riccati_qp.py builds one library per number of states and inputs): the
   compiler unrolls and vectorises the small stage products. */
#ifndef RQP_NX
#error "define RQP_NX and RQP_NU"
#endif
#ifndef RQP_NP
#define RQP_NP 0 /* the last RQP_NP state entries are free at knot 0 (parameters, e.g. a time scale) */
#endif
#define RQP_NZ (RQP_NX + RQP_NU)
#define RQP_E0 (RQP_NX - RQP_NP) /* knot 0's first free entry: its free states, then its inputs */
#define RQP_N0 (RQP_NP + RQP_NU)
#define RQP_NY (RQP_NX + 2 * RQP_NU)

typedef struct {
    int N;
} rqp_dims;

/* Cholesky of the n x n symmetric a (row-major, lower triangle used) in place; 0 when positive definite */
static int chol(int n, double* a)
{
    for (int j = 0; j < n; ++j) {
        double d = a[j * n + j];
        for (int k = 0; k < j; ++k) d -= a[j * n + k] * a[j * n + k];
        if (!(d > 0.0)) return 1;
        d = sqrt(d);
        a[j * n + j] = d;
        for (int i = j + 1; i < n; ++i) {
            double v = a[i * n + j];
            for (int k = 0; k < j; ++k) v -= a[i * n + k] * a[j * n + k];
            a[i * n + j] = v / d;
        }
    }
    return 0;
}

/* x := a^-1 x with a's Cholesky factor (n x n) */
static void chol_solve(int n, const double* l, double* x)
{
    for (int i = 0; i < n; ++i) {
        double v = x[i];
        for (int k = 0; k < i; ++k) v -= l[i * n + k] * x[k];
        x[i] = v / l[i * n + i];
    }
    for (int i = n - 1; i >= 0; --i) {
        double v = x[i];
        for (int k = i + 1; k < n; ++k) v -= l[k * n + i] * x[k];
        x[i] = v / l[i * n + i];
    }
}

/* Gaussian elimination with partial pivoting: m (n x n, destroyed) x = b (overwritten); 0 when regular */
static int lu_solve(int n, double* m, double* b)
{
    double scale = 0.0;
    for (int i = 0; i < n * n; ++i) scale = fmax(scale, fabs(m[i]));
    if (!(scale > 0.0)) return 1;
    for (int j = 0; j < n; ++j) {
        int p = j;
        for (int i = j + 1; i < n; ++i)
            if (fabs(m[i * n + j]) > fabs(m[p * n + j])) p = i;
        if (!(fabs(m[p * n + j]) > 1e-13 * scale)) return 1;
        if (p != j) {
            for (int k = 0; k < n; ++k) {
                double t = m[j * n + k];
                m[j * n + k] = m[p * n + k];
                m[p * n + k] = t;
            }
            double t = b[j];
            b[j] = b[p];
            b[p] = t;
        }
        for (int i = j + 1; i < n; ++i) {
            double f = m[i * n + j] / m[j * n + j];
            if (f == 0.0) continue;
            for (int k = j; k < n; ++k) m[i * n + k] -= f * m[j * n + k];
            b[i] -= f * b[j];
        }
    }
    for (int i = n - 1; i >= 0; --i) {
        double v = b[i];
        for (int k = i + 1; k < n; ++k) v -= m[i * n + k] * b[k];
        b[i] = v / m[i * n + i];
    }
    return 0;
}

typedef struct {
    rqp_dims d;
    const double *T, *ct, *Hy, *gy, *lo, *hi;
    const int* act;   /* (N+1) nz: 0 free, -1 at lower, +1 at upper, 2 equality */
    double rho;       /* the penalty on held state rows' residuals (zero at any point of the active set) */
    /* factorisation, per stage */
    double *P, *p, *K, *kk, *S, *L;
    int* nfree;       /* per stage (and the du_0 pseudo-stage at index N) */
    int* fact_act;    /* (N+1) nz: the active set the stages' factors are of (when fact_valid) */
    int fact_valid;
    int* fidx;        /* (N+1) nu: free control indices, then fixed ones */
    double *L0;       /* du_0's factor */
    /* solution */
    double *s, *w, *ptot;
    /* state rows */
    int nrow, maxrow;
    int *rk, *ri;
    double* rb;
    double *cs, *cw, *cp, *ck; /* per row: states (N+1) nz, controls N nu, linear terms (N+1) nz, feedforwards N nu */
    double *M, *nu_;
    double* tmp;
} rqp_ws;

#define IDX(k, i) ((k) * RQP_NZ + (i))

/* the entry of knot k + 1 that stage k's input i is (k = -1: knot 0's free entry i, its free states then du_0) */
static int input_entry(int k, int i)
{
    return k < 0 ? RQP_E0 + i : IDX(k + 1, RQP_NX + i);
}

/* the value a fixed input of stage k (k = -1: knot 0's free entries) is held at */
static double fixed_value(const rqp_ws* W, int k, int i)
{
    int j = input_entry(k, i);
    return W->act[j] < 0 ? W->lo[j] : W->hi[j];
}

static int input_fixed(const rqp_ws* W, int k, int i)
{
    return W->act[input_entry(k, i)] != 0;
}

/* rho/2 (s_i - b)^2 on each state row of knot k the active set holds, added to the value function there: zero with
   a zero gradient wherever the rows hold, so the active set's QP keeps its solution and its multipliers, but the
   recursion now sees the held rows (a pinned end state makes the stages before it a stabilised, well-conditioned
   regulator instead of an open-loop propagation through the unstable modes, and lends the curvature the rows
   give the constrained problem to the reduced Hessians) */
static void held_penalty(rqp_ws* W, int k)
{
    const int nz = RQP_NZ, nx = RQP_NX;
    if (!(W->rho > 0.0)) return;
    double* Pk = W->P + (size_t)k * nz * nz;
    double* pk = W->p + (size_t)k * nz;
    for (int i = 0; i < nx; ++i) {
        int a = W->act[IDX(k, i)];
        if (!a) continue;
        double b = a < 0 ? W->lo[IDX(k, i)] : W->hi[IDX(k, i)];
        Pk[i * nz + i] += W->rho;
        pk[i] -= W->rho * b;
    }
}

/* backward Riccati pass with the inputs of the active set held; 1 when a reduced Hessian is not positive definite */
static int backward(rqp_ws* W)
{
    const rqp_dims* d = &W->d;
    const int nz = RQP_NZ, nu = RQP_NU, ny = RQP_NY, nx = RQP_NX;
    double* PA = W->tmp;              /* nz nz */
    double* PB = PA + nz * nz;        /* nz nu */
    double* pc = PB + nz * nu;        /* nz */
    double* R = pc + nz;              /* nu nu */
    double* r = R + nu * nu;          /* nu */
    double* q = r + nu;               /* nz */
    double* RF = q + nz;              /* nu nu */
    /* the stages above the last change of the active set since the last factorisation keep their factors (the
       same data, the same operations: the same numbers): a held input of knot k changes stage k - 1, a held state
       row of knot k the value function there, so stage k (k < N) or every stage (k = N) */
    int ks = d->N - 1, top = 1;
    if (W->fact_valid) {
        ks = -1;
        top = 0;
        for (int k = 1; k <= d->N; ++k)
            for (int i = 0; i < nz; ++i) {
                const int j = IDX(k, i);
                if (W->act[j] == W->fact_act[j]) continue;
                const int c = i >= nx ? k - 1 : (k == d->N ? d->N - 1 : k);
                if (i < nx && k == d->N) top = 1;
                if (c > ks) ks = c;
            }
    }
    W->fact_valid = 0;
    if (top) {
        memset(W->P + (size_t)d->N * nz * nz, 0, sizeof(double) * nz * nz);
        memset(W->p + d->N * nz, 0, sizeof(double) * nz);
        held_penalty(W, d->N);
    }
    for (int k = ks; k >= 0; --k) {
        const double* Tk = W->T + (size_t)k * nz * ny;
        const double* H = W->Hy + (size_t)k * ny * ny;
        const double* g = W->gy + (size_t)k * ny;
        const double* P1 = W->P + (size_t)(k + 1) * nz * nz;
        const double* p1 = W->p + (size_t)(k + 1) * nz;
        double* Pk = W->P + (size_t)k * nz * nz;
        double* pk = W->p + (size_t)k * nz;
        double* S = W->S + (size_t)k * nu * nz;
        double* Kk = W->K + (size_t)k * nu * nz;
        double* kk = W->kk + (size_t)k * nu;
        double* L = W->L + (size_t)k * nu * nu;
        int* fi = W->fidx + k * nu;
        /* PA = P1 A, PB = P1 B, pc = P1 c + p1 */
        for (int i = 0; i < nz; ++i) {
            for (int j = 0; j < nz; ++j) {
                double v = 0.0;
                for (int m = 0; m < nz; ++m) v += P1[i * nz + m] * Tk[m * ny + j];
                PA[i * nz + j] = v;
            }
            for (int j = 0; j < nu; ++j) {
                double v = 0.0;
                for (int m = 0; m < nz; ++m) v += P1[i * nz + m] * Tk[m * ny + nz + j];
                PB[i * nu + j] = v;
            }
            double v = p1[i];
            for (int m = 0; m < nx; ++m) v += P1[i * nz + m] * W->ct[(size_t)k * nx + m];
            pc[i] = v;
        }
        /* Q = Hss + A' PA (into Pk), S = Hws + B' PA, R = Hww + B' PB, q = gs + A' pc, r = gw + B' pc */
        for (int i = 0; i < nz; ++i) {
            for (int j = i; j < nz; ++j) {
                double v = H[i * ny + j];
                for (int m = 0; m < nz; ++m) v += Tk[m * ny + i] * PA[m * nz + j];
                Pk[i * nz + j] = v;
            }
            double v = g[i];
            for (int m = 0; m < nz; ++m) v += Tk[m * ny + i] * pc[m];
            q[i] = v;
        }
        for (int i = 0; i < nu; ++i) {
            for (int j = 0; j < nz; ++j) {
                double v = H[(nz + i) * ny + j];
                for (int m = 0; m < nz; ++m) v += Tk[m * ny + nz + i] * PA[m * nz + j];
                S[i * nz + j] = v;
            }
            for (int j = 0; j < nu; ++j) {
                double v = H[(nz + i) * ny + nz + j];
                for (int m = 0; m < nz; ++m) v += Tk[m * ny + nz + i] * PB[m * nu + j];
                R[i * nu + j] = v;
            }
            double v = g[nz + i];
            for (int m = 0; m < nz; ++m) v += Tk[m * ny + nz + i] * pc[m];
            r[i] = v;
        }
        /* free inputs first in fi; the fixed ones move r and q */
        int nf = 0;
        for (int i = 0; i < nu; ++i)
            if (!input_fixed(W, k, i)) fi[nf++] = i;
        int t = nf;
        for (int i = 0; i < nu; ++i)
            if (input_fixed(W, k, i)) fi[t++] = i;
        W->nfree[k] = nf;
        for (int a = nf; a < nu; ++a) {
            int i = fi[a];
            double v = fixed_value(W, k, i);
            for (int j = 0; j < nu; ++j) r[j] += R[j * nu + i] * v;
            for (int j = 0; j < nz; ++j) q[j] += S[i * nz + j] * v;
        }
        for (int a = 0; a < nf; ++a)
            for (int b = 0; b < nf; ++b) RF[a * nf + b] = R[fi[a] * nu + fi[b]];
        if (nf && chol(nf, RF)) return 1;
        memcpy(L, RF, sizeof(double) * nf * nf);
        /* K_F = -R_FF^-1 S_F, k_F = -R_FF^-1 r_F (rows of the fixed inputs zero) */
        memset(Kk, 0, sizeof(double) * nu * nz);
        memset(kk, 0, sizeof(double) * nu);
        double col[16];
        for (int j = 0; j < nz; ++j) {
            for (int a = 0; a < nf; ++a) col[a] = -S[fi[a] * nz + j];
            if (nf) chol_solve(nf, L, col);
            for (int a = 0; a < nf; ++a) Kk[fi[a] * nz + j] = col[a];
        }
        for (int a = 0; a < nf; ++a) col[a] = -r[fi[a]];
        if (nf) chol_solve(nf, L, col);
        for (int a = 0; a < nf; ++a) kk[fi[a]] = col[a];
        /* P = Q + S_F' K_F (symmetric: upper computed, mirrored), p = q + S_F' k_F */
        for (int i = 0; i < nz; ++i) {
            for (int j = i; j < nz; ++j) {
                double v = Pk[i * nz + j];
                for (int a = 0; a < nf; ++a) v += S[fi[a] * nz + i] * Kk[fi[a] * nz + j];
                Pk[i * nz + j] = v;
                Pk[j * nz + i] = v;
            }
            double v = q[i];
            for (int a = 0; a < nf; ++a) v += S[fi[a] * nz + i] * kk[fi[a]];
            pk[i] = v;
        }
        if (k >= 1) held_penalty(W, k);
    }
    /* knot 0's pseudo-stage (its free states and du_0): R0 = P_0's block of them */
    {
        const int e0 = RQP_E0, n0 = RQP_N0;
        int* fi = W->fidx + d->N * nu;
        int nf = 0;
        for (int i = 0; i < n0; ++i)
            if (!input_fixed(W, -1, i)) fi[nf++] = i;
        int t = nf;
        for (int i = 0; i < n0; ++i)
            if (input_fixed(W, -1, i)) fi[t++] = i;
        W->nfree[d->N] = nf;
        for (int a = 0; a < nf; ++a)
            for (int b = 0; b < nf; ++b) W->L0[a * nf + b] = W->P[(e0 + fi[a]) * nz + e0 + fi[b]];
        if (nf && chol(nf, W->L0)) return 1;
    }
    memcpy(W->fact_act, W->act, sizeof(int) * (size_t)(d->N + 1) * nz);
    W->fact_valid = 1;
    return 0;
}

/* forward pass from the linear terms lin ((N+1) nz, the value functions' gradients at zero) and feedforwards ff
   (N nu): states s ((N+1) nz), controls w (N nu); homogeneous: no c, the fixed inputs at zero */
static void forward(rqp_ws* W, const double* lin, const double* ff, int homogeneous, double* s, double* w)
{
    const rqp_dims* d = &W->d;
    const int nz = RQP_NZ, nu = RQP_NU, ny = RQP_NY, nx = RQP_NX;
    double col[16];
    /* knot 0's free entries */
    {
        const int e0 = RQP_E0, n0 = RQP_N0;
        const int* fi = W->fidx + d->N * nu;
        int nf = W->nfree[d->N];
        memset(s, 0, sizeof(double) * nz);
        for (int a = nf; a < n0; ++a) s[e0 + fi[a]] = homogeneous ? 0.0 : fixed_value(W, -1, fi[a]);
        for (int a = 0; a < nf; ++a) {
            double v = lin[e0 + fi[a]];
            for (int b = nf; b < n0; ++b) v += W->P[(e0 + fi[a]) * nz + e0 + fi[b]] * s[e0 + fi[b]];
            col[a] = -v;
        }
        if (nf) chol_solve(nf, W->L0, col);
        for (int a = 0; a < nf; ++a) s[e0 + fi[a]] = col[a];
    }
    for (int k = 0; k < d->N; ++k) {
        const double* Tk = W->T + (size_t)k * nz * ny;
        const double* sk = s + (size_t)k * nz;
        double* sn = s + (size_t)(k + 1) * nz;
        double* wk = w + (size_t)k * nu;
        const double* Kk = W->K + (size_t)k * nu * nz;
        const int* fi = W->fidx + k * nu;
        int nf = W->nfree[k];
        for (int a = 0; a < nf; ++a) {
            int i = fi[a];
            double v = ff[(size_t)k * nu + i];
            for (int j = 0; j < nz; ++j) v += Kk[i * nz + j] * sk[j];
            wk[i] = v;
        }
        for (int a = nf; a < nu; ++a) wk[fi[a]] = homogeneous ? 0.0 : fixed_value(W, k, fi[a]);
        for (int i = 0; i < nz; ++i) {
            double v = (!homogeneous && i < nx) ? W->ct[(size_t)k * nx + i] : 0.0;
            for (int j = 0; j < nz; ++j) v += Tk[i * ny + j] * sk[j];
            for (int j = 0; j < nu; ++j) v += Tk[i * ny + nz + j] * wk[j];
            sn[i] = v;
        }
    }
}

/* backward pass of linear terms alone: a term v on state entry i of knot kr (all_rows: every held row's multiplier
   on its entry); the value functions' gradients cp ((N+1) nz) and the feedforwards ck (N nu) they cause */
static void column(rqp_ws* W, int kr, int i, double v, int all_rows, double* cp, double* ck)
{
    const rqp_dims* d = &W->d;
    const int nz = RQP_NZ, nu = RQP_NU, ny = RQP_NY;
    double col[16];
    int top = kr;
    if (all_rows) {
        top = 0;
        for (int r = 0; r < W->nrow; ++r) top = W->rk[r] > top ? W->rk[r] : top;
    }
    memset(cp, 0, sizeof(double) * (d->N + 1) * nz);
    memset(ck, 0, sizeof(double) * d->N * nu);
    if (all_rows) {
        for (int r = 0; r < W->nrow; ++r) cp[(size_t)W->rk[r] * nz + W->ri[r]] += W->nu_[r];
    } else {
        cp[(size_t)kr * nz + i] = v;
    }
    for (int k = top - 1; k >= 0; --k) {
        const double* Tk = W->T + (size_t)k * nz * ny;
        const double* p1 = cp + (size_t)(k + 1) * nz;
        const double* S = W->S + (size_t)k * nu * nz;
        const double* L = W->L + (size_t)k * nu * nu;
        const int* fi = W->fidx + k * nu;
        int nf = W->nfree[k];
        double* pk = cp + (size_t)k * nz;
        for (int a = 0; a < nf; ++a) {
            double u = 0.0;
            for (int m = 0; m < nz; ++m) u += Tk[m * ny + nz + fi[a]] * p1[m];
            col[a] = -u;
        }
        if (nf) chol_solve(nf, L, col);
        for (int a = 0; a < nf; ++a) ck[(size_t)k * nu + fi[a]] = col[a];
        for (int j = 0; j < nz; ++j) {
            double u = pk[j];
            for (int m = 0; m < nz; ++m) u += Tk[m * ny + j] * p1[m];
            for (int a = 0; a < nf; ++a) u += S[fi[a] * nz + j] * col[a];
            pk[j] = u;
        }
    }
}

/* every held row's response to a unit multiplier, all rows in one sweep over the stages (each stage's data read
   once for all rows), read at every row: M[a][r] = the state entry of row a when row r's multiplier is one */
static void responses(rqp_ws* W)
{
    const rqp_dims* d = &W->d;
    const int nz = RQP_NZ, nu = RQP_NU, ny = RQP_NY, nx = RQP_NX, N = d->N, nr = W->nrow;
    double* Pm = W->cs;            /* nr nz: the value functions' gradients, a row each */
    double* Km = W->cp;            /* N nr nu: the feedforwards */
    double* X = W->cs;             /* forward: nr nz (Pm is done by then) */
    double tmp[16], pn[RQP_NZ], xn[RQP_NZ], w[RQP_NU];
    memset(Pm, 0, sizeof(double) * nz * nr);
    for (int r = 0; r < nr; ++r)
        if (W->rk[r] == N) Pm[r * nz + W->ri[r]] = 1.0;
    for (int k = N - 1; k >= 0; --k) {
        const double* Tk = W->T + (size_t)k * nz * ny;
        const double* S = W->S + (size_t)k * nu * nz;
        const double* L = W->L + (size_t)k * nu * nu;
        const int* fi = W->fidx + k * nu;
        const int nf = W->nfree[k];
        for (int r = 0; r < nr; ++r) {
            double* p1 = Pm + r * nz;
            double* kk = Km + ((size_t)k * nr + r) * nu;
            for (int i = 0; i < nu; ++i) kk[i] = 0.0;
            for (int a = 0; a < nf; ++a) {
                double u = 0.0;
                for (int m = 0; m < nz; ++m) u += Tk[m * ny + nz + fi[a]] * p1[m];
                tmp[a] = -u;
            }
            if (nf) chol_solve(nf, L, tmp);
            for (int a = 0; a < nf; ++a) kk[fi[a]] = tmp[a];
            for (int j = 0; j < nz; ++j) {
                double u = 0.0;
                for (int m = 0; m < nz; ++m) u += Tk[m * ny + j] * p1[m];
                for (int a = 0; a < nf; ++a) u += S[fi[a] * nz + j] * tmp[a];
                pn[j] = u;
            }
            if (k >= 1 && W->rk[r] == k) pn[W->ri[r]] += 1.0;
            for (int j = 0; j < nz; ++j) p1[j] = pn[j];
        }
    }
    {
        const int* fi = W->fidx + N * nu;
        const int nf = W->nfree[N];
        for (int r = 0; r < nr; ++r) {
            double* x = X + r * nz;
            for (int a = 0; a < nf; ++a) tmp[a] = -x[RQP_E0 + fi[a]];
            if (nf) chol_solve(nf, W->L0, tmp);
            for (int i = 0; i < nz; ++i) x[i] = 0.0;
            for (int a = 0; a < nf; ++a) x[RQP_E0 + fi[a]] = tmp[a];
        }
    }
    for (int k = 0; k < N; ++k) {
        const double* Tk = W->T + (size_t)k * nz * ny;
        const double* Kf = W->K + (size_t)k * nu * nz;
        const int* fi = W->fidx + k * nu;
        const int nf = W->nfree[k];
        for (int r = 0; r < nr; ++r) {
            double* x = X + r * nz;
            const double* kk = Km + ((size_t)k * nr + r) * nu;
            for (int i = 0; i < nu; ++i) w[i] = 0.0;
            for (int a = 0; a < nf; ++a) {
                const int i = fi[a];
                double u = kk[i];
                for (int j = 0; j < nz; ++j) u += Kf[i * nz + j] * x[j];
                w[i] = u;
            }
            for (int i = 0; i < nz; ++i) {
                double u = 0.0;
                for (int j = 0; j < nz; ++j) u += Tk[i * ny + j] * x[j];
                for (int j = 0; j < nu; ++j) u += Tk[i * ny + nz + j] * w[j];
                xn[i] = u;
            }
            for (int i = 0; i < nz; ++i) x[i] = xn[i];
        }
        for (int a = 0; a < nr; ++a)
            if (W->rk[a] == k + 1)
                for (int r = 0; r < nr; ++r) W->M[a * nr + r] = X[r * nz + W->ri[a]];
    }
}

/* the equality-constrained QP of the active set: W->s, W->w, W->ptot, W->nu_; 0, 1 (not convex), 2 (rows dependent) */
static int solve_active(rqp_ws* W)
{
    const rqp_dims* d = &W->d;
    const int nz = RQP_NZ, nu = RQP_NU, N = d->N, nx = RQP_NX;
    const size_t ns = (size_t)(N + 1) * nz, nw = (size_t)N * nu;
    if (backward(W)) return 1;
    /* the active state rows */
    W->nrow = 0;
    for (int k = 1; k <= N; ++k)
        for (int i = 0; i < nx; ++i) {
            int a = W->act[IDX(k, i)];
            if (!a) continue;
            if (W->nrow >= W->maxrow) return 2;
            int r = W->nrow++;
            W->rk[r] = k;
            W->ri[r] = i;
            W->rb[r] = a < 0 ? W->lo[IDX(k, i)] : W->hi[IDX(k, i)];
        }
    forward(W, W->p, W->kk, 0, W->s, W->w);
    memcpy(W->ptot, W->p, sizeof(double) * ns);
    int nr = W->nrow;
    if (!nr) return 0;
    responses(W);
    for (int a = 0; a < nr; ++a) W->nu_[a] = W->rb[a] - W->s[IDX(W->rk[a], W->ri[a])];
    if (lu_solve(nr, W->M, W->nu_)) return 2;
    /* the solution: all the rows' terms at once, added to the base pass's, then one forward pass */
    column(W, 0, 0, 0.0, 1, W->cp, W->ck);
    for (size_t j = 0; j < ns; ++j) W->ptot[j] += W->cp[j];
    for (size_t j = 0; j < nw; ++j) W->ck[j] += W->kk[j];
    forward(W, W->ptot, W->ck, 0, W->s, W->w);
    (void)nx;
    return 0;
}

/* the gradient of the Lagrangian in the held input i of stage k (k = -1: knot 0's free entry i) */
static double input_gradient(const rqp_ws* W, int k, int i)
{
    const int nz = RQP_NZ, nu = RQP_NU, ny = RQP_NY;
    if (k < 0) {
        const int e = RQP_E0 + i;
        double v = W->ptot[e];
        for (int j = 0; j < nz; ++j) v += W->P[e * nz + j] * W->s[j];
        return v;
    }
    const double* Tk = W->T + (size_t)k * nz * ny;
    const double* H = W->Hy + (size_t)k * ny * ny;
    const double* P1 = W->P + (size_t)(k + 1) * nz * nz;
    const double* p1 = W->ptot + (size_t)(k + 1) * nz;
    const double* sk = W->s + (size_t)k * nz;
    const double* sn = W->s + (size_t)(k + 1) * nz;
    const double* wk = W->w + (size_t)k * nu;
    double v = W->gy[(size_t)k * ny + nz + i];
    for (int j = 0; j < nz; ++j) v += H[(nz + i) * ny + j] * sk[j];
    for (int j = 0; j < nu; ++j) v += H[(nz + i) * ny + nz + j] * wk[j];
    for (int m = 0; m < nz; ++m) {
        double g = p1[m];
        for (int j = 0; j < nz; ++j) g += P1[m * nz + j] * sn[j];
        v += Tk[m * ny + nz + i] * g;
    }
    return v;
}

static size_t work_doubles(int N, int nx, int nu, int mr)
{
    const size_t nz = nx + nu, ns = (size_t)(N + 1) * nz, nw = (size_t)N * nu;
    return (size_t)(N + 1) * nz * nz + ns + nw * nz + nw + nw * nz + (size_t)N * nu * nu + RQP_N0 * RQP_N0 + ns + nw + ns
           + 2 * ns + 2 * nw + (size_t)mr * mr + 2 * (size_t)mr + 4 * nz * nz + 8 * nz + 8 * (size_t)nu * nu
           + 2 * nz * (size_t)mr + nw * (size_t)mr + (size_t)nu * mr;
}

static size_t work_ints(int N, int nx, int nu, int mr)
{
    return (size_t)(N + 1) * (nu + 1) + RQP_NP + 2 * (size_t)mr + 4 * (size_t)(N + 1) * (nx + nu);
}

/* Sizes of rqp_solve's work arrays for at most maxrow held state rows: doubles, then ints. */
void rqp_work_size(int N, int nx, int nu, int maxrow, long* doubles, long* ints)
{
    int mr = maxrow > 0 ? maxrow : 1;
    *doubles = (long)work_doubles(N, nx, nu, mr);
    *ints = (long)work_ints(N, nx, nu, mr);
}

/* Solve the QP (module docstring of riccati_qp.py). act ((N+1) nz) holds the active set to start from and returns
   the final one; dz ((N+1) nz) the step, nb ((N+1) nz) the bound multipliers (CasADi's sign: positive at an upper
   bound). At most maxrow state rows held at once (work arrays sized by rqp_work_size). Returns 0 (optimal), 1 (a
   reduced Hessian not positive definite), 2 (held rows dependent, or more than maxrow: the QP may be infeasible),
   3 (iteration limit); iters the active sets tried. */
int rqp_solve(int N, int nx, int nu, const double* T, const double* ct, const double* Hy, const double* gy,
              const double* lo, const double* hi, int* act, double* dz, double* nb, int max_iter, double tol,
              int maxrow, double rho, double* buf, int* ibuf, int* iters)
{
    rqp_ws W;
    rqp_dims* d = &W.d;
    memset(&W, 0, sizeof W);
    d->N = N;
    const int nz = RQP_NZ;
    const size_t ns = (size_t)(N + 1) * nz, nw = (size_t)N * nu;
    int status = 3, it = 0;
    if (RQP_N0 > 16 || nx != RQP_NX || nu != RQP_NU) return 1;
    W.T = T;
    W.ct = ct;
    W.Hy = Hy;
    W.gy = gy;
    W.lo = lo;
    W.hi = hi;
    W.act = act;
    W.rho = rho;
    int mr = maxrow > 0 ? maxrow : 1;
    W.maxrow = maxrow;
    double* o = buf;
    W.P = o; o += (size_t)(N + 1) * nz * nz;
    W.p = o; o += ns;
    W.K = o; o += nw * nz;
    W.kk = o; o += nw;
    W.S = o; o += nw * nz;
    W.L = o; o += (size_t)N * nu * nu;
    W.L0 = o; o += RQP_N0 * RQP_N0;
    W.s = o; o += ns;
    W.w = o; o += nw;
    W.ptot = o; o += ns;
    W.cs = o; o += 2 * (size_t)nz * mr;
    W.cp = o; o += (ns > nw * (size_t)mr ? ns : nw * (size_t)mr);
    W.cw = o; o += (nw > (size_t)nu * mr ? nw : (size_t)nu * mr);
    W.ck = o; o += nw;
    W.rb = o; o += mr;
    W.M = o; o += (size_t)mr * mr;
    W.nu_ = o; o += mr;
    W.tmp = o;
    int* io = ibuf;
    W.nfree = io; io += N + 1;
    W.fidx = io; io += (N + 1) * nu + RQP_NP;
    W.rk = io; io += mr;
    W.ri = io; io += mr;
    int* prev = io; io += ns;
    int* work = io; io += ns;
    int* blocked = io; io += ns; /* bounds whose addition made the held rows dependent: left out of this solve */
    W.fact_act = io;
    W.fact_valid = 0;
    memset(blocked, 0, sizeof(int) * ns);
    /* equalities always held; infinite sides never */
    for (int k = 0; k <= N; ++k)
        for (int i = 0; i < nz; ++i) {
            int j = IDX(k, i);
            if (k == 0 && i < RQP_E0) { act[j] = 0; continue; }
            if (isfinite(lo[j]) && lo[j] == hi[j]) act[j] = 2;
            else if (act[j] == 2 || (act[j] < 0 && !isfinite(lo[j])) || (act[j] > 0 && !isfinite(hi[j]))) act[j] = 0;
        }
    int single = 0, last = -1;
    for (it = 1; it <= max_iter; ++it) {
        int st = solve_active(&W);
        if (st == 1 && it == 1) { /* not convex where it starts: with fewer bounds held the indefinite direction
                                     stays free, so no reset to the equalities would help */
            status = 1;
            break;
        }
        if (st && it == 1) { /* the starting guess is no use: from the equalities alone */
            for (size_t j = 0; j < ns; ++j)
                if (act[j] != 2) act[j] = 0;
            st = solve_active(&W);
        } else if (st == 2 && single && last >= 0 && prev[last] == 0) {
            /* adding that one bound made the held rows dependent (the rows need the input it holds): undo it and
               leave it out; the other candidates go on */
            memcpy(act, prev, sizeof(int) * ns);
            blocked[last] = 1;
            st = solve_active(&W);
        } else if (st && !single) { /* a simultaneous change made the rows dependent: back, one change at a time */
            memcpy(act, prev, sizeof(int) * ns);
            single = 1;
            st = solve_active(&W);
        }
        if (st) { status = st; break; }
        /* candidates: violated free bounds, held bounds with the wrong multiplier sign */
        double worst = 0.0;
        int wj = -1, wa = 0, nchange = 0, nblocked = 0;
        memcpy(work, act, sizeof(int) * ns);
        for (int k = 0; k <= N; ++k)
            for (int i = 0; i < nz; ++i) {
                int j = IDX(k, i);
                if (k == 0 && i < RQP_E0) continue;
                int a = act[j];
                if (a == 2) continue;
                double val = (i < nx) ? W.s[j] : (k == 0 ? W.s[i] : W.w[(size_t)(k - 1) * nu + i - nx]);
                double viol = 0.0;
                int na = a;
                if (a == 0) {
                    if (val > hi[j] + tol) { viol = val - hi[j]; na = 1; }
                    else if (val < lo[j] - tol) { viol = lo[j] - val; na = -1; }
                } else {
                    double lam;
                    if (k == 0) lam = -input_gradient(&W, -1, i - RQP_E0);
                    else if (i >= nx) lam = -input_gradient(&W, k - 1, i - nx);
                    else {
                        lam = 0.0;
                        for (int r = 0; r < W.nrow; ++r)
                            if (W.rk[r] == k && W.ri[r] == i) lam = W.nu_[r];
                    }
                    if (a * lam < -tol) { viol = fabs(lam); na = 0; }
                }
                if (na != a && a == 0 && blocked[j]) {
                    nblocked++;
                    continue;
                }
                if (na != a) {
                    work[j] = na;
                    nchange++;
                    if (viol > worst) { worst = viol; wj = j; wa = na; }
                }
            }
        if (!nchange) { status = nblocked ? 2 : 0; break; } /* a violated bound left out: no answer */
        if (it >= 10) single = 1;
        memcpy(prev, act, sizeof(int) * ns);
        last = single ? wj : -1;
        if (single) act[wj] = wa;
        else memcpy(act, work, sizeof(int) * ns);
    }
    if (iters) *iters = it;
    if (status == 0) {
        memset(nb, 0, sizeof(double) * ns);
        memcpy(dz, W.s, sizeof(double) * ns);
        for (int i = 0; i < RQP_E0; ++i) dz[i] = 0.0;
        for (int i = RQP_E0; i < nz; ++i)
            if (act[i]) nb[i] = -input_gradient(&W, -1, i - RQP_E0);
        for (int k = 1; k <= N; ++k)
            for (int i = nx; i < nz; ++i) {
                int j = IDX(k, i);
                if (act[j]) nb[j] = -input_gradient(&W, k - 1, i - nx);
            }
        for (int r = 0; r < W.nrow; ++r) nb[IDX(W.rk[r], W.ri[r])] = W.nu_[r];
    }
    return status;
}
