/* Compiled core of tracking: pairing, the attitude fit, the covariance sandwich.
 *
 * Tracking matches a few dozen detections to a few dozen predicted stars and fits the attitude
 * to the pairs, two to four times per frame. Its NumPy form (identify/tracking.py,
 * solve/tracking/star_noise.py) spends its time in the per-call overhead of a few hundred
 * small array operations, not in the arithmetic. These kernels do the same arithmetic in C:
 *
 * pair      the nearest and second-nearest predicted star of each detection (squared chords
 *           summed x, y, z in NumPy's order), the ambiguity test and the one-detection-per-star
 *           rule of TrackingIdentifier._pair: equal to the NumPy form bit for bit.
 * wahba     the attitude matrix maximising sum w_i b_i . (C r_i) (Wahba's problem) from the
 *           largest eigenvector of Davenport's K matrix (cyclic Jacobi), or, for two pairs on
 *           request, the rotation that aligns the first pair exactly and the second as closely
 *           as it can (TRIAD; scipy's align_vectors with an infinite primary weight); then the
 *           residual chords and angles. The NumPy form solves the same problem by LAPACK's SVD:
 *           the two agree to rounding (1e-15 rad in the attitude, a few ulp).
 * match     TrackingIdentifier's loop: pair, fit, shrink the radius, pair again, in one call
 *           (the same steps; the predicted vectors ref C^T summed without BLAS: equal to
 *           rounding, so the pairs are the NumPy form's but at a tie with the radius).
 * fisher_inverse  F^-1 of eq. 21 with covariance()'s singularity test (attitude/
 *           covariance.py; its eigenvalues by Jacobi rotations, the inverse by the adjugate:
 *           equal to rounding, 1e-13 relative for the condition numbers of a star field).
 * weighted_fit  wahba with weights sigma^-2 and fisher_inverse of the same stars, and the
 *           Wahba loss, in one call (the solver's fit of its matched stars).
 * sandwich  P = F^-1 (sum_i w_i^2 J_i^T G_i C_i G_i^T J_i) F^-1 of star_noise.py: the same sums
 *           in another order (1e-13 relative).
 * unblended whether each matched star has no other predicted star within the blend distance
 *           (solve/tracking/field.py): the same squared distances, minimum and square root,
 *           equal to the NumPy form bit for bit.
 *
 * Built with -ffp-contract=off (no fused multiply-add), as an optional extension: without a C
 * compiler the package uses the NumPy form. No NumPy headers: arrays arrive through the buffer
 * protocol (float64 / int64, C order).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static int check(Py_buffer *b, Py_ssize_t bytes, const char *what)
{
    if (b->len < bytes) {
        PyErr_Format(PyExc_ValueError, "_trackc: %s holds %zd bytes, needs %zd", what, b->len,
                     bytes);
        return 0;
    }
    return 1;
}

/* The pairing of pair() below; first, counts: scratch (n,), (m,). Returns the pairs kept. */
static Py_ssize_t pair_core(const double *v, Py_ssize_t n, const double *c, Py_ssize_t m,
                            double bound2, double ratio, int64_t *det, int64_t *star,
                            int64_t *first, int64_t *counts, Py_ssize_t *n_ambiguous)
{
    Py_ssize_t k = 0, n_amb = 0;
    for (Py_ssize_t j = 0; j < m; j++)
        counts[j] = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        double best = INFINITY, second = INFINITY;
        Py_ssize_t arg = 0;
        for (Py_ssize_t j = 0; j < m; j++) {
            double dx = v[3 * i] - c[3 * j], dy = v[3 * i + 1] - c[3 * j + 1],
                   dz = v[3 * i + 2] - c[3 * j + 2];
            double d2 = dx * dx + dy * dy;
            d2 = d2 + dz * dz;
            if (d2 < best) { /* argmin: the first of equal minima */
                second = best;
                best = d2;
                arg = j;
            } else if (d2 < second) {
                second = d2;
            }
        }
        first[i] = -1;
        if (m == 0 || !(best < bound2))
            continue;
        int clear = 1;
        if (m > 1)
            clear = (second >= bound2) || (sqrt(second) >= ratio * sqrt(best));
        if (!clear) {
            n_amb++;
            continue;
        }
        first[i] = arg;
        counts[arg]++;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        if (first[i] < 0)
            continue;
        if (counts[first[i]] == 1) {
            det[k] = i;
            star[k] = first[i];
            k++;
        } else {
            n_amb++;
        }
    }
    *n_ambiguous = n_amb;
    return k;
}

/* pair(v, n, cam, m, bound2, ratio, det_out, star_out, work) -> (k, n_ambiguous)
 * v (n, 3), cam (m, 3) float64; det_out, star_out int64 (n,); work int64 (n + m,). */
static PyObject *pair(PyObject *self, PyObject *args)
{
    Py_buffer vb, cb, db, sb, wb;
    Py_ssize_t n, m;
    double bound2, ratio;
    PyObject *result = NULL;
    if (!PyArg_ParseTuple(args, "y*ny*nddw*w*w*", &vb, &n, &cb, &m, &bound2, &ratio, &db, &sb,
                          &wb))
        return NULL;
    if (check(&vb, n * 3 * 8, "v") && check(&cb, m * 3 * 8, "cam") &&
        check(&db, n * 8, "det_out") && check(&sb, n * 8, "star_out") &&
        check(&wb, (n + m) * 8, "work")) {
        int64_t *first = wb.buf;
        Py_ssize_t n_amb;
        Py_ssize_t k = pair_core(vb.buf, n, cb.buf, m, bound2, ratio, db.buf, sb.buf, first,
                                 first + n, &n_amb);
        result = Py_BuildValue("nn", k, n_amb);
    }
    PyBuffer_Release(&vb);
    PyBuffer_Release(&cb);
    PyBuffer_Release(&db);
    PyBuffer_Release(&sb);
    PyBuffer_Release(&wb);
    return result;
}

/* Eigenvector of the largest eigenvalue of the symmetric 4 x 4 matrix a (destroyed): cyclic
 * Jacobi rotations until the off-diagonal part vanishes to rounding. */
static void top_eigenvector(double a[4][4], double q[4])
{
    double v[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
    for (int sweep = 0; sweep < 50; sweep++) {
        double off = 0.0, diag = 0.0;
        for (int p = 0; p < 4; p++) {
            diag += a[p][p] * a[p][p];
            for (int r = p + 1; r < 4; r++)
                off += a[p][r] * a[p][r];
        }
        if (off <= 1e-36 * diag || off == 0.0)
            break;
        for (int p = 0; p < 3; p++) {
            for (int r = p + 1; r < 4; r++) {
                double apr = a[p][r];
                if (fabs(apr) <= 1e-18 * (fabs(a[p][p]) + fabs(a[r][r]))) {
                    a[p][r] = a[r][p] = 0.0; /* below the rounding of the diagonal */
                    continue;
                }
                double theta = (a[r][r] - a[p][p]) / (2.0 * apr);
                double t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                double cs = 1.0 / sqrt(t * t + 1.0), sn = t * cs;
                for (int k = 0; k < 4; k++) { /* columns p, r */
                    double akp = a[k][p], akr = a[k][r];
                    a[k][p] = cs * akp - sn * akr;
                    a[k][r] = sn * akp + cs * akr;
                }
                for (int k = 0; k < 4; k++) { /* rows p, r */
                    double apk = a[p][k], ark = a[r][k];
                    a[p][k] = cs * apk - sn * ark;
                    a[r][k] = sn * apk + cs * ark;
                }
                for (int k = 0; k < 4; k++) {
                    double vkp = v[k][p], vkr = v[k][r];
                    v[k][p] = cs * vkp - sn * vkr;
                    v[k][r] = sn * vkp + cs * vkr;
                }
            }
        }
    }
    int best = 0;
    for (int p = 1; p < 4; p++)
        if (a[p][p] > a[best][best])
            best = p;
    double norm = 0.0;
    for (int k = 0; k < 4; k++)
        norm += v[k][best] * v[k][best];
    norm = sqrt(norm);
    for (int k = 0; k < 4; k++)
        q[k] = v[k][best] / norm;
}

static void cross(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

static int unit(double a[3])
{
    double s = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    if (!(s > 0))
        return 0;
    a[0] /= s;
    a[1] /= s;
    a[2] /= s;
    return 1;
}

/* TRIAD: c maps the frame (r1, r1 x r2, ...) onto (b1, b1 x b2, ...). 0 if the pairs are
 * parallel. */
static int triad(const double *b, const double *r, double c[9])
{
    double tb[3][3], tr[3][3];
    memcpy(tb[0], b, 3 * sizeof(double));
    memcpy(tr[0], r, 3 * sizeof(double));
    if (!unit(tb[0]) || !unit(tr[0]))
        return 0;
    cross(tb[0], b + 3, tb[1]);
    cross(tr[0], r + 3, tr[1]);
    if (!unit(tb[1]) || !unit(tr[1]))
        return 0;
    cross(tb[0], tb[1], tb[2]);
    cross(tr[0], tr[1], tr[2]);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            c[3 * i + j] = tb[0][i] * tr[0][j] + tb[1][i] * tr[1][j] + tb[2][i] * tr[2][j];
    return 1;
}

/* The fit of wahba() below (n >= 2). */
static void fit_core(const double *b, const double *r, const double *w, Py_ssize_t n,
                     int two_triad, double *c, double *resid, double *chord2)
{
    if (!(two_triad && n == 2 && triad(b, r, c))) {
        double B[3][3] = {{0}};
        for (Py_ssize_t i = 0; i < n; i++)
            for (int j = 0; j < 3; j++)
                for (int k = 0; k < 3; k++)
                    B[j][k] += (w ? w[i] : 1.0) * b[3 * i + j] * r[3 * i + k];
        double sigma = B[0][0] + B[1][1] + B[2][2];
        double z[3] = {B[1][2] - B[2][1], B[2][0] - B[0][2], B[0][1] - B[1][0]};
        double K[4][4];
        for (int j = 0; j < 3; j++) {
            for (int k = 0; k < 3; k++)
                K[j][k] = B[j][k] + B[k][j] - (j == k ? sigma : 0.0);
            K[j][3] = K[3][j] = z[j];
        }
        K[3][3] = sigma;
        double q[4];
        top_eigenvector(K, q);
        /* Markley's attitude matrix of q = (q1, q2, q3, q4), q4 the scalar part */
        double x = q[0], y = q[1], zz = q[2], s = q[3];
        c[0] = x * x - y * y - zz * zz + s * s;
        c[1] = 2.0 * (x * y + zz * s);
        c[2] = 2.0 * (x * zz - y * s);
        c[3] = 2.0 * (x * y - zz * s);
        c[4] = -x * x + y * y - zz * zz + s * s;
        c[5] = 2.0 * (y * zz + x * s);
        c[6] = 2.0 * (x * zz + y * s);
        c[7] = 2.0 * (y * zz - x * s);
        c[8] = -x * x - y * y + zz * zz + s * s;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        double h = 0.0;
        for (int j = 0; j < 3; j++) {
            double p = c[3 * j] * r[3 * i] + c[3 * j + 1] * r[3 * i + 1] +
                       c[3 * j + 2] * r[3 * i + 2];
            double d = b[3 * i + j] - p;
            h += d * d;
        }
        chord2[i] = h;
        double half = sqrt(h) / 2.0;
        resid[i] = 2.0 * asin(half < 1.0 ? half : 1.0);
    }
}

/* wahba(body, ref, w, n, two_triad, c_out, resid_out, chord2_out)
 * body, ref (n, 3); w (n,) weights (any positive scale); c_out (3, 3): body ~ c ref. */
static PyObject *wahba(PyObject *self, PyObject *args)
{
    Py_buffer bb, rb, wb, cb, eb, hb;
    Py_ssize_t n;
    int two_triad;
    PyObject *result = NULL;
    if (!PyArg_ParseTuple(args, "y*y*y*npw*w*w*", &bb, &rb, &wb, &n, &two_triad, &cb, &eb, &hb))
        return NULL;
    if (!check(&bb, n * 3 * 8, "body") || !check(&rb, n * 3 * 8, "ref") ||
        !check(&wb, n * 8, "w") || !check(&cb, 9 * 8, "c_out") ||
        !check(&eb, n * 8, "resid_out") || !check(&hb, n * 8, "chord2_out"))
        goto done;
    if (n < 2) {
        PyErr_SetString(PyExc_ValueError, "_trackc.wahba: at least 2 pairs are needed");
        goto done;
    }
    fit_core(bb.buf, rb.buf, wb.buf, n, two_triad, cb.buf, eb.buf, hb.buf);
    Py_INCREF(Py_None);
    result = Py_None;
done:
    PyBuffer_Release(&bb);
    PyBuffer_Release(&rb);
    PyBuffer_Release(&wb);
    PyBuffer_Release(&cb);
    PyBuffer_Release(&eb);
    PyBuffer_Release(&hb);
    return result;
}

static int compare_doubles(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* cam = ref c^T: each star's predicted camera vector. */
static void rotate_all(const double *ref, Py_ssize_t m, const double *c, double *cam)
{
    for (Py_ssize_t i = 0; i < m; i++)
        for (int k = 0; k < 3; k++)
            cam[3 * i + k] = ref[3 * i] * c[3 * k] + ref[3 * i + 1] * c[3 * k + 1] +
                             ref[3 * i + 2] * c[3 * k + 2];
}

/* Fit the pairs (det, star) with equal weights (two by TRIAD): c, resid (k,). */
static void fit_pairs(const double *v, const double *ref, const int64_t *det,
                      const int64_t *star, Py_ssize_t k, double *scratch, double *c,
                      double *resid)
{
    double *b = scratch, *r = scratch + 3 * k, *chord2 = scratch + 6 * k;
    for (Py_ssize_t i = 0; i < k; i++)
        for (int j = 0; j < 3; j++) {
            b[3 * i + j] = v[3 * det[i] + j];
            r[3 * i + j] = ref[3 * star[i] + j];
        }
    fit_core(b, r, NULL, k, 1, c, resid, chord2);
}

/* match(v, n, ref, m, prior, radius, min_radius, ratio, mad, root, det_out, star_out, c_out,
 *       resid_out) -> (k, n_ambiguous, radius)
 * TrackingIdentifier's loop (identify/tracking.py): pair within ``radius`` of the prior
 * (prior (3, 3), ICRS -> camera); if at least two pairs, up to three times fit them, shrink the
 * radius to max(5 mad median(resid) / root, min_radius) and pair again, until the pairs stand
 * (or fewer than two are left: the last fit kept). k < 2: no fit (c_out, resid_out unset). */
static PyObject *match(PyObject *self, PyObject *args)
{
    Py_buffer vb, rb, pb, db, sb, cb, eb;
    Py_ssize_t n, m;
    double radius, min_radius, ratio, mad, root;
    PyObject *result = NULL;
    if (!PyArg_ParseTuple(args, "y*ny*ny*dddddw*w*w*w*", &vb, &n, &rb, &m, &pb, &radius,
                          &min_radius, &ratio, &mad, &root, &db, &sb, &cb, &eb))
        return NULL;
    int64_t *iwork = NULL;
    double *dwork = NULL;
    if (!check(&vb, n * 3 * 8, "v") || !check(&rb, m * 3 * 8, "ref") ||
        !check(&pb, 9 * 8, "prior") || !check(&db, n * 8, "det_out") ||
        !check(&sb, n * 8, "star_out") || !check(&cb, 9 * 8, "c_out") ||
        !check(&eb, n * 8, "resid_out"))
        goto done;
    iwork = malloc(sizeof(int64_t) * (3 * n + m + 1));
    dwork = malloc(sizeof(double) * (3 * m + 9 * n + n + 1));
    if (!iwork || !dwork) {
        PyErr_NoMemory();
        goto done;
    }
    {
        const double *v = vb.buf, *ref = rb.buf;
        int64_t *det = db.buf, *star = sb.buf;
        int64_t *det_new = iwork, *star_new = iwork + n, *first = iwork + 2 * n,
                *counts = iwork + 3 * n;
        double *cam = dwork, *scratch = dwork + 3 * m, *sorted = scratch + 9 * n;
        double *c = cb.buf, *resid = eb.buf;
        Py_ssize_t n_amb, k;
        double chord = 2.0 * sin((radius < M_PI ? radius : M_PI) / 2.0);
        rotate_all(ref, m, pb.buf, cam);
        k = pair_core(v, n, cam, m, chord * chord, ratio, det, star, first, counts, &n_amb);
        if (k >= 2) {
            int fitted = 0;
            for (int it = 0; it < 3; it++) {
                fit_pairs(v, ref, det, star, k, scratch, c, resid);
                fitted = 1;
                memcpy(sorted, resid, sizeof(double) * k);
                qsort(sorted, k, sizeof(double), compare_doubles);
                Py_ssize_t h = k / 2;
                double med = (k % 2) ? sorted[h] : (sorted[h - 1] + sorted[h]) / 2;
                double sigma = mad * med / root;
                double grown = 5.0 * sigma > min_radius ? 5.0 * sigma : min_radius;
                radius = radius < grown ? radius : grown;
                chord = 2.0 * sin((radius < M_PI ? radius : M_PI) / 2.0);
                rotate_all(ref, m, c, cam);
                Py_ssize_t k_new = pair_core(v, n, cam, m, chord * chord, ratio, det_new,
                                             star_new, first, counts, &n_amb);
                if (k_new < 2)
                    break;
                fitted = k_new == k;
                for (Py_ssize_t i = 0; fitted && i < k; i++)
                    fitted = det_new[i] == det[i] && star_new[i] == star[i];
                memcpy(det, det_new, sizeof(int64_t) * k_new);
                memcpy(star, star_new, sizeof(int64_t) * k_new);
                k = k_new;
                if (fitted)
                    break;
            }
            if (!fitted)
                fit_pairs(v, ref, det, star, k, scratch, c, resid);
        }
        result = Py_BuildValue("nnd", k, n_amb, radius);
    }
done:
    free(iwork);
    free(dwork);
    PyBuffer_Release(&vb);
    PyBuffer_Release(&rb);
    PyBuffer_Release(&pb);
    PyBuffer_Release(&db);
    PyBuffer_Release(&sb);
    PyBuffer_Release(&cb);
    PyBuffer_Release(&eb);
    return result;
}

/* sandwich(body, g, cov, w, inv, n, out): out = inv (sum_i w_i^2 S_i^T G_i C_i G_i^T S_i) inv
 * body (n, 3), g (n, 3, 2), cov (n, 2, 2), w (n,), inv (3, 3), out (3, 3); S_i = [b_i]x. */
static PyObject *sandwich(PyObject *self, PyObject *args)
{
    Py_buffer bb, gb, cb, wb, ib, ob;
    Py_ssize_t n;
    PyObject *result = NULL;
    if (!PyArg_ParseTuple(args, "y*y*y*y*y*nw*", &bb, &gb, &cb, &wb, &ib, &n, &ob))
        return NULL;
    if (!check(&bb, n * 3 * 8, "body") || !check(&gb, n * 6 * 8, "g") ||
        !check(&cb, n * 4 * 8, "cov") || !check(&wb, n * 8, "w") || !check(&ib, 9 * 8, "inv") ||
        !check(&ob, 9 * 8, "out"))
        goto done;
    {
        const double *b = bb.buf, *g = gb.buf, *cv = cb.buf, *w = wb.buf, *inv = ib.buf;
        double *out = ob.buf;
        double mid[3][3] = {{0}};
        for (Py_ssize_t i = 0; i < n; i++) {
            const double *gi = g + 6 * i, *ci = cv + 4 * i, *bi = b + 3 * i;
            double gc[3][2], nz[3][3], s[3][3], ns[3][3];
            for (int a = 0; a < 3; a++)
                for (int k = 0; k < 2; k++)
                    gc[a][k] = gi[2 * a] * ci[k] + gi[2 * a + 1] * ci[2 + k];
            for (int a = 0; a < 3; a++)
                for (int k = 0; k < 3; k++)
                    nz[a][k] = gc[a][0] * gi[2 * k] + gc[a][1] * gi[2 * k + 1];
            s[0][0] = s[1][1] = s[2][2] = 0.0;
            s[0][1] = -bi[2];
            s[0][2] = bi[1];
            s[1][2] = -bi[0];
            s[1][0] = bi[2];
            s[2][0] = -bi[1];
            s[2][1] = bi[0];
            for (int a = 0; a < 3; a++)
                for (int k = 0; k < 3; k++)
                    ns[a][k] = nz[a][0] * s[0][k] + nz[a][1] * s[1][k] + nz[a][2] * s[2][k];
            double w2 = w[i] * w[i];
            for (int j = 0; j < 3; j++)
                for (int k = 0; k < 3; k++)
                    mid[j][k] += w2 * (s[0][j] * ns[0][k] + s[1][j] * ns[1][k] + s[2][j] * ns[2][k]);
        }
        double t[3][3];
        for (int j = 0; j < 3; j++)
            for (int k = 0; k < 3; k++)
                t[j][k] = inv[3 * j] * mid[0][k] + inv[3 * j + 1] * mid[1][k] +
                          inv[3 * j + 2] * mid[2][k];
        for (int j = 0; j < 3; j++)
            for (int k = 0; k < 3; k++)
                out[3 * j + k] = t[j][0] * inv[k] + t[j][1] * inv[3 + k] + t[j][2] * inv[6 + k];
        Py_INCREF(Py_None);
        result = Py_None;
    }
done:
    PyBuffer_Release(&bb);
    PyBuffer_Release(&gb);
    PyBuffer_Release(&cb);
    PyBuffer_Release(&wb);
    PyBuffer_Release(&ib);
    PyBuffer_Release(&ob);
    return result;
}

/* unblended(x, y, near, n, cat_index, m, blend_px, out) -> None
 * out[j] (uint8) = 1 where matched star cat_index[j] has no other predicted star within
 * blend_px: over the predicted stars with finite x and y (near ascending), the star's position
 * by a left binary search of cat_index[j] in their near (the last where beyond), the least
 * dx^2 + dy^2 to the others, compared after its square root; every out 1 with fewer than two
 * such stars (track_kernels.unblended_numpy). */
static PyObject *unblended(PyObject *self, PyObject *args)
{
    Py_buffer xb, yb, nb, cb, ob;
    Py_ssize_t n, m;
    double blend;
    PyObject *result = NULL;
    double *xo = NULL;
    if (!PyArg_ParseTuple(args, "y*y*y*ny*ndw*", &xb, &yb, &nb, &n, &cb, &m, &blend, &ob))
        return NULL;
    if (!check(&xb, n * 8, "x") || !check(&yb, n * 8, "y") || !check(&nb, n * 8, "near") ||
        !check(&cb, m * 8, "cat_index") || !check(&ob, m, "out"))
        goto done;
    xo = malloc((n > 0 ? n : 1) * (2 * sizeof(double) + sizeof(int64_t)));
    if (xo == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    {
        const double *x = xb.buf, *y = yb.buf;
        const int64_t *near = nb.buf, *cat = cb.buf;
        unsigned char *out = ob.buf;
        double *yo = xo + n;
        int64_t *no = (int64_t *)(yo + n);
        Py_ssize_t k = 0;
        for (Py_ssize_t i = 0; i < n; i++)
            if (isfinite(x[i]) && isfinite(y[i])) {
                xo[k] = x[i];
                yo[k] = y[i];
                no[k++] = near[i];
            }
        for (Py_ssize_t j = 0; j < m; j++) {
            if (k < 2) {
                out[j] = 1;
                continue;
            }
            Py_ssize_t lo = 0, hi = k; /* np.searchsorted(no, cat[j]) (side "left") */
            while (lo < hi) {
                Py_ssize_t mid = lo + (hi - lo) / 2;
                if (no[mid] < cat[j])
                    lo = mid + 1;
                else
                    hi = mid;
            }
            Py_ssize_t w = lo < k - 1 ? lo : k - 1;
            double best = INFINITY;
            for (Py_ssize_t i = 0; i < k; i++) {
                if (i == w)
                    continue; /* the star itself */
                double dx = xo[w] - xo[i], dy = yo[w] - yo[i];
                double d2 = dx * dx + dy * dy;
                if (d2 < best)
                    best = d2;
            }
            out[j] = sqrt(best) > blend;
        }
        Py_INCREF(Py_None);
        result = Py_None;
    }
done:
    free(xo);
    PyBuffer_Release(&xb);
    PyBuffer_Release(&yb);
    PyBuffer_Release(&nb);
    PyBuffer_Release(&cb);
    PyBuffer_Release(&ob);
    return result;
}

/* F^-1 of weighted unit vectors into out (3, 3): 1, or 0 (out unset) where F is not finite
 * or singular (fisher_inverse below). */
static int fisher_core(const double *b, const double *sg, Py_ssize_t n, double rcond,
                       double *out)
{
    double f[3][3] = {{0}}, sw = 0.0;
    for (Py_ssize_t i = 0; i < n; i++) {
        double w = pow(sg[i], -2.0);
        sw += w;
        for (int j = 0; j < 3; j++)
            for (int k = 0; k < 3; k++)
                f[j][k] -= w * b[3 * i + j] * b[3 * i + k];
    }
    int finite = isfinite(sw);
    for (int j = 0; j < 3; j++) {
        f[j][j] += sw;
        for (int k = 0; k < 3; k++)
            finite = finite && isfinite(f[j][k]);
    }
    int ok = 0;
    if (finite) {
        double a[3][3], lo, hi;
        memcpy(a, f, sizeof(a));
        for (int sweep = 0; sweep < 50; sweep++) {
            double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
            if (off == 0.0)
                break;
            for (int p = 0; p < 2; p++)
                for (int r = p + 1; r < 3; r++) {
                    double apr = a[p][r];
                    if (fabs(apr) <= 1e-18 * (fabs(a[p][p]) + fabs(a[r][r]))) {
                        a[p][r] = a[r][p] = 0.0;
                        continue;
                    }
                    double theta = (a[r][r] - a[p][p]) / (2.0 * apr);
                    double t = (theta >= 0 ? 1.0 : -1.0) /
                               (fabs(theta) + sqrt(theta * theta + 1.0));
                    double cs = 1.0 / sqrt(t * t + 1.0), sn = t * cs;
                    for (int k = 0; k < 3; k++) {
                        double akp = a[k][p], akr = a[k][r];
                        a[k][p] = cs * akp - sn * akr;
                        a[k][r] = sn * akp + cs * akr;
                    }
                    for (int k = 0; k < 3; k++) {
                        double apk = a[p][k], ark = a[r][k];
                        a[p][k] = cs * apk - sn * ark;
                        a[r][k] = sn * apk + cs * ark;
                    }
                }
        }
        lo = fmin(a[0][0], fmin(a[1][1], a[2][2]));
        hi = fmax(a[0][0], fmax(a[1][1], a[2][2]));
        ok = hi > 0 && lo > rcond * hi;
    }
    if (ok) {
        double c00 = f[1][1] * f[2][2] - f[1][2] * f[2][1];
        double c01 = f[1][2] * f[2][0] - f[1][0] * f[2][2];
        double c02 = f[1][0] * f[2][1] - f[1][1] * f[2][0];
        double det = f[0][0] * c00 + f[0][1] * c01 + f[0][2] * c02;
        out[0] = c00 / det;
        out[1] = (f[0][2] * f[2][1] - f[0][1] * f[2][2]) / det;
        out[2] = (f[0][1] * f[1][2] - f[0][2] * f[1][1]) / det;
        out[3] = c01 / det;
        out[4] = (f[0][0] * f[2][2] - f[0][2] * f[2][0]) / det;
        out[5] = (f[0][2] * f[1][0] - f[0][0] * f[1][2]) / det;
        out[6] = c02 / det;
        out[7] = (f[0][1] * f[2][0] - f[0][0] * f[2][1]) / det;
        out[8] = (f[0][0] * f[1][1] - f[0][1] * f[1][0]) / det;
    }
    return ok;
}

/* fisher_inverse(body, sigma, n, rcond, out) -> bool
 * F = sum_i sigma_i^-2 (I - b_i b_i^T) (Fialho & Mortari 2019 eq. 21, attitude/covariance.py)
 * and out = F^-1 (adjugate / determinant); False (out unset) where F is not finite or singular
 * by covariance()'s test: largest eigenvalue <= 0 or smallest <= rcond x largest (cyclic
 * Jacobi eigenvalues). */
static PyObject *fisher_inverse(PyObject *self, PyObject *args)
{
    Py_buffer bb, sb, ob;
    Py_ssize_t n;
    double rcond;
    PyObject *result = NULL;
    if (!PyArg_ParseTuple(args, "y*y*ndw*", &bb, &sb, &n, &rcond, &ob))
        return NULL;
    if (!check(&bb, n * 3 * 8, "body") || !check(&sb, n * 8, "sigma") ||
        !check(&ob, 9 * 8, "out"))
        goto done;
    result = PyBool_FromLong(fisher_core(bb.buf, sb.buf, n, rcond, ob.buf));

done:
    PyBuffer_Release(&bb);
    PyBuffer_Release(&sb);
    PyBuffer_Release(&ob);
    return result;
}

/* weighted_fit(body, ref, sigma, n, rcond, c_out, resid_out, chord2_out, cov_out)
 *     -> (covariance found, loss)
 * wahba() with weights sigma^-2 and fisher_inverse() of the same stars in one call (the
 * solver's fit of matched stars, attitude/robust.py); loss = 1/2 sum_i chord2_i / sigma_i^2. */
static PyObject *weighted_fit(PyObject *self, PyObject *args)
{
    Py_buffer bb, rb, sb, cb, eb, hb, ob;
    Py_ssize_t n;
    double rcond;
    PyObject *result = NULL;
    double wbuf[256], *w = wbuf;
    if (!PyArg_ParseTuple(args, "y*y*y*ndw*w*w*w*", &bb, &rb, &sb, &n, &rcond, &cb, &eb, &hb,
                          &ob))
        return NULL;
    if (!check(&bb, n * 3 * 8, "body") || !check(&rb, n * 3 * 8, "ref") ||
        !check(&sb, n * 8, "sigma") || !check(&cb, 9 * 8, "c_out") ||
        !check(&eb, n * 8, "resid_out") || !check(&hb, n * 8, "chord2_out") ||
        !check(&ob, 9 * 8, "cov_out"))
        goto done;
    if (n < 2) {
        PyErr_SetString(PyExc_ValueError, "_trackc.weighted_fit: at least 2 pairs are needed");
        goto done;
    }
    if (n > 256 && (w = malloc(n * sizeof(double))) == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    {
        const double *sg = sb.buf, *h = hb.buf;
        for (Py_ssize_t i = 0; i < n; i++)
            w[i] = pow(sg[i], -2.0);
        int ok = fisher_core(bb.buf, sg, n, rcond, ob.buf);
        fit_core(bb.buf, rb.buf, w, n, 0, cb.buf, eb.buf, hb.buf);
        double loss = 0.0;
        for (Py_ssize_t i = 0; i < n; i++)
            loss += h[i] * w[i];
        result = Py_BuildValue("Nd", PyBool_FromLong(ok), 0.5 * loss);
    }
    if (w != wbuf)
        free(w);
done:
    PyBuffer_Release(&bb);
    PyBuffer_Release(&rb);
    PyBuffer_Release(&sb);
    PyBuffer_Release(&cb);
    PyBuffer_Release(&eb);
    PyBuffer_Release(&hb);
    PyBuffer_Release(&ob);
    return result;
}

static PyMethodDef methods[] = {
    {"pair", pair, METH_VARARGS, "Nearest predicted star of each detection (see _trackc.c)."},
    {"wahba", wahba, METH_VARARGS, "Attitude matrix and residuals of paired vectors."},
    {"match", match, METH_VARARGS, "TrackingIdentifier's pair-fit-pair loop."},
    {"fisher_inverse", fisher_inverse, METH_VARARGS, "Inverse Fisher matrix of weighted stars."},
    {"weighted_fit", weighted_fit, METH_VARARGS, "wahba and fisher_inverse of one star set."},
    {"sandwich", sandwich, METH_VARARGS, "Covariance of the weighted SVD attitude."},
    {"unblended", unblended, METH_VARARGS, "Matched stars with no predicted neighbour near."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_trackc", NULL, -1, methods};

PyMODINIT_FUNC PyInit__trackc(void) { return PyModule_Create(&module); }
