/* Compiled kernels of the forward model (windows.py, fit.py, psf_table.py).
 *
 *   static_gaussian   windows.py's evaluate for one time node and a Gaussian PSF: every
 *                     (source, group) pair's box, its pixel fractions the outer product of the
 *                     1-D pixel integrals along the rows and the columns (psf.py's
 *                     gaussian_pixel_1d: 0.5 (erf(a / sqrt2) - erf(b / sqrt2)), a, b = (d +- 1/2)
 *                     / sigma); the template set where the source's flux is fitted in the group
 *                     (templates (G, M + 1, H, W): the slot M, the background's, not written),
 *                     its light (flux x template) added to the fixed light where it is given;
 *                     the geometric Jacobian flux x -(dx/dp py dpx + dy/dp dpy px) added, and
 *                     with ``width`` the derivative with respect to sigma (stamps.py's
 *                     _gaussian_width_1d) appended as the last parameter;
 *   normal_equations  fit.py's _normal_equations' sums per group: A = L W L^T, B = L W J^T,
 *                     C = J W J^T, u = L W r, v = J W r over the group's pixels (L the linear
 *                     rows, J the geometric ones, W the weights, r the residuals);
 *   table_grid        psf_table.py's SplineTable.grid: a tabulated PSF's cubic B-spline and its
 *                     gradient on grids of whole pixels (one phase between nodes per grid).
 *
 * The NumPy forms are the reference (tests/model/test_model_kernels.py holds them equal to within
 * rounding: the sums' order differs). Built by setup.py as an optional extension (no fused
 * multiply-adds); without a C compiler the package runs the NumPy forms. No NumPy headers:
 * arrays arrive through the buffer protocol, C-contiguous float64 and int64.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define INV_SQRT2 0.70710678118654752440
#define INV_SQRT2PI 0.39894228040143267794

static int check(Py_buffer *b, Py_ssize_t bytes, const char *name)
{
    if (b->len < bytes) {
        PyErr_Format(PyExc_ValueError, "%s: buffer of %zd bytes, %zd needed", name, b->len,
                     bytes);
        return -1;
    }
    return 0;
}

/* pixel fractions p, d p / d d and d p / d sigma of n pixels at offsets d0, d0 + 1, ... */
static void pixel_1d(double d0, Py_ssize_t n, double sigma, double *p, double *dp, double *ds)
{
    for (Py_ssize_t i = 0; i < n; i++) {
        double d = d0 + (double)i;
        double a = (d + 0.5) / sigma, b = (d - 0.5) / sigma;
        double ea = exp(-0.5 * a * a), eb = exp(-0.5 * b * b);
        p[i] = 0.5 * (erf(a * INV_SQRT2) - erf(b * INV_SQRT2));
        dp[i] = (ea - eb) * INV_SQRT2PI / sigma;
        ds[i] = -(a * ea - b * eb) * INV_SQRT2PI / sigma;
    }
}

typedef struct {
    const int64_t *group, *source, *slot, *box, *row0, *col0;
    const double *x, *y, *dx, *dy, *flux;
    double *templates, *fixed, *jac;
    Py_ssize_t q, h, w, m, p, n_par;
    double sigma;
    int gradient, width;
} Eval;

static int static_gaussian(const Eval *e)
{
    Py_ssize_t side = e->h > e->w ? e->h : e->w;
    double *buf = malloc(sizeof(double) * 6 * (size_t)side);
    if (buf == NULL) return -1;
    double *py = buf, *dpy = buf + side, *sy = buf + 2 * side;
    double *px = buf + 3 * side, *dpx = buf + 4 * side, *sx = buf + 5 * side;
    Py_ssize_t hw = e->h * e->w;
    for (Py_ssize_t k = 0; k < e->q; k++) {
        int64_t g = e->group[k], s = e->source[k], slot = e->slot[k];
        const int64_t *bx = e->box + 4 * k;
        Py_ssize_t nr = (Py_ssize_t)(bx[1] - bx[0]), nc = (Py_ssize_t)(bx[3] - bx[2]);
        if (nr <= 0 || nc <= 0) continue;
        pixel_1d((double)(e->row0[g] + bx[0]) - e->y[s], nr, e->sigma, py, dpy, sy);
        pixel_1d((double)(e->col0[g] + bx[2]) - e->x[s], nc, e->sigma, px, dpx, sx);
        double f = e->flux[s];
        double *tmpl = slot >= 0 ? e->templates + (g * (e->m + 1) + slot) * hw : NULL;
        double *fix = slot >= 0 ? NULL : e->fixed + g * hw;
        const double *ax = e->dx + s * e->p, *ay = e->dy + s * e->p;
        for (Py_ssize_t i = 0; i < nr; i++) {
            Py_ssize_t row = (bx[0] + i) * e->w + bx[2];
            for (Py_ssize_t j = 0; j < nc; j++) {
                double t = py[i] * px[j];
                if (tmpl != NULL) tmpl[row + j] = t;
                else fix[row + j] += f * t;
                if (!e->gradient) continue;
                double gx = py[i] * dpx[j], gy = dpy[i] * px[j];
                double *jg = e->jac + g * e->n_par * hw + row + j;
                for (Py_ssize_t c = 0; c < e->p; c++)
                    jg[c * hw] += f * -(ax[c] * gx + ay[c] * gy);
                if (e->width) jg[e->p * hw] += f * (sy[i] * px[j] + py[i] * sx[j]);
            }
        }
    }
    free(buf);
    return 0;
}

/* static_gaussian(group, source, slot, box, row0, col0, x, y, dx, dy, flux,
 *                 q, g, h, w, m, p, sigma, gradient, width, templates, fixed, jac) */
static PyObject *py_static_gaussian(PyObject *self, PyObject *args)
{
    Py_buffer b[14];
    Py_ssize_t g;
    Eval e;
    memset(b, 0, sizeof(b));
    if (!PyArg_ParseTuple(args, "y*y*y*y*y*y*y*y*y*y*y*nnnnnndppw*w*w*", &b[0], &b[1], &b[2],
                          &b[3], &b[4], &b[5], &b[6], &b[7], &b[8], &b[9], &b[10], &e.q, &g,
                          &e.h, &e.w, &e.m, &e.p, &e.sigma, &e.gradient, &e.width, &b[11],
                          &b[12], &b[13]))
        return NULL;
    PyObject *out = NULL;
    Py_ssize_t n_src = b[6].len / 8;
    e.n_par = e.p + (e.width ? 1 : 0);
    Py_ssize_t hw = e.h * e.w;
    if (check(&b[0], 8 * e.q, "group") || check(&b[1], 8 * e.q, "source") ||
        check(&b[2], 8 * e.q, "slot") || check(&b[3], 32 * e.q, "box") ||
        check(&b[4], 8 * g, "row0") || check(&b[5], 8 * g, "col0") ||
        check(&b[7], 8 * n_src, "y") || check(&b[8], 8 * n_src * e.p, "dx") ||
        check(&b[9], 8 * n_src * e.p, "dy") || check(&b[10], 8 * n_src, "flux") ||
        check(&b[11], 8 * g * (e.m + 1) * hw, "templates") || check(&b[12], 8 * g * hw, "fixed") ||
        (e.gradient && check(&b[13], 8 * g * e.n_par * hw, "jac")))
        goto done;
    e.group = b[0].buf; e.source = b[1].buf; e.slot = b[2].buf; e.box = b[3].buf;
    e.row0 = b[4].buf; e.col0 = b[5].buf; e.x = b[6].buf; e.y = b[7].buf;
    e.dx = b[8].buf; e.dy = b[9].buf; e.flux = b[10].buf;
    e.templates = b[11].buf; e.fixed = b[12].buf; e.jac = b[13].buf;
    for (Py_ssize_t k = 0; k < e.q; k++) {  /* every index inside its array */
        const int64_t *bx = e.box + 4 * k;
        if (e.group[k] < 0 || e.group[k] >= g || e.source[k] < 0 || e.source[k] >= n_src ||
            e.slot[k] >= e.m || bx[0] < 0 || bx[1] > e.h || bx[2] < 0 || bx[3] > e.w) {
            PyErr_Format(PyExc_ValueError, "pair %zd: index outside its array", k);
            goto done;
        }
    }
    if (static_gaussian(&e) != 0) {
        PyErr_NoMemory();
        goto done;
    }
    out = Py_NewRef(Py_None);
done:
    for (int i = 0; i < 14; i++)
        if (b[i].obj != NULL) PyBuffer_Release(&b[i]);
    return out;
}

/* normal_equations(lin, jac, weight, resid, g, m, p, n, a, b, c, u, v): per group, over its n
 * pixels, A (m, m), B (m, p), C (p, p), u (m), v (p); lin (g, m, n), jac (g, p, n). */
static PyObject *py_normal_equations(PyObject *self, PyObject *args)
{
    Py_buffer b[9];
    Py_ssize_t g, m, p, n;
    memset(b, 0, sizeof(b));
    if (!PyArg_ParseTuple(args, "y*y*y*y*nnnnw*w*w*w*w*", &b[0], &b[1], &b[2], &b[3], &g, &m,
                          &p, &n, &b[4], &b[5], &b[6], &b[7], &b[8]))
        return NULL;
    PyObject *out = NULL;
    if (check(&b[0], 8 * g * m * n, "lin") || check(&b[1], 8 * g * p * n, "jac") ||
        check(&b[2], 8 * g * n, "weight") || check(&b[3], 8 * g * n, "resid") ||
        check(&b[4], 8 * g * m * m, "a") || check(&b[5], 8 * g * m * p, "b") ||
        check(&b[6], 8 * g * p * p, "c") || check(&b[7], 8 * g * m, "u") ||
        check(&b[8], 8 * g * p, "v"))
        goto done;
    const double *lin = b[0].buf, *jac = b[1].buf, *wt = b[2].buf, *res = b[3].buf;
    double *a = b[4].buf, *bb = b[5].buf, *c = b[6].buf, *u = b[7].buf, *v = b[8].buf;
    Py_ssize_t r = m + p;
    const double **rows = malloc(sizeof(double *) * (size_t)(r > 0 ? r : 1));
    double *acc = calloc((size_t)(r * r + r), sizeof(double));
    if (rows == NULL || acc == NULL) {
        free(rows);
        free(acc);
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t gi = 0; gi < g; gi++) {
        for (Py_ssize_t i = 0; i < m; i++) rows[i] = lin + (gi * m + i) * n;
        for (Py_ssize_t i = 0; i < p; i++) rows[m + i] = jac + (gi * p + i) * n;
        const double *w = wt + gi * n, *e = res + gi * n;
        memset(acc, 0, sizeof(double) * (size_t)(r * r + r));
        for (Py_ssize_t k = 0; k < n; k++) {
            double wk = w[k];
            if (wk == 0.0) continue;
            double we = wk * e[k];
            for (Py_ssize_t i = 0; i < r; i++) {
                double xi = rows[i][k];
                if (xi == 0.0) continue;
                double wx = wk * xi;
                double *ai = acc + i * r;
                for (Py_ssize_t j = i; j < r; j++) ai[j] += wx * rows[j][k];
                acc[r * r + i] += xi * we;
            }
        }
        for (Py_ssize_t i = 0; i < r; i++)
            for (Py_ssize_t j = 0; j < i; j++) acc[i * r + j] = acc[j * r + i];
        for (Py_ssize_t i = 0; i < m; i++) {
            for (Py_ssize_t j = 0; j < m; j++) a[(gi * m + i) * m + j] = acc[i * r + j];
            for (Py_ssize_t j = 0; j < p; j++) bb[(gi * m + i) * p + j] = acc[i * r + m + j];
            u[gi * m + i] = acc[r * r + i];
        }
        for (Py_ssize_t i = 0; i < p; i++) {
            for (Py_ssize_t j = 0; j < p; j++) c[(gi * p + i) * p + j] = acc[(m + i) * r + m + j];
            v[gi * p + i] = acc[r * r + m + i];
        }
    }
    free(rows);
    free(acc);
    out = Py_NewRef(Py_None);
done:
    for (int i = 0; i < 9; i++)
        if (b[i].obj != NULL) PyBuffer_Release(&b[i]);
    return out;
}

/* the cubic B-spline's weights at phase t in [0, 1) and their d/dt (psf_table.py's _weights) */
static void bspline_weights(double t, double *w, double *dw)
{
    double s = 1.0 - t, t2 = t * t, t3 = t * t * t;
    w[0] = s * s * s / 6.0;
    w[1] = (4.0 - 6.0 * t2 + 3.0 * t3) / 6.0;
    w[2] = (1.0 + 3.0 * (t + t2 - t3)) / 6.0;
    w[3] = t3 / 6.0;
    dw[0] = -0.5 * s * s;
    dw[1] = -2.0 * t + 1.5 * t2;
    dw[2] = 0.5 + t - 1.5 * t2;
    dw[3] = 0.5 * t2;
}

/* table_grid(coef, m, radius, per_px, pad, x0, y0, n, ny, nx, gradient, v, gx, gy):
 * psf_table.py's SplineTable.grid: n grids of ny x nx whole pixels at offsets x0 + j, y0 + i
 * from their star, the spline of the (m, m) coefficients; gx, gy written with gradient. */
static PyObject *py_table_grid(PyObject *self, PyObject *args)
{
    Py_buffer b[6];
    Py_ssize_t m, per_px, pad, n, ny, nx;
    double radius;
    int gradient;
    memset(b, 0, sizeof(b));
    if (!PyArg_ParseTuple(args, "y*ndnny*y*nnnpw*w*w*", &b[0], &m, &radius, &per_px, &pad,
                          &b[1], &b[2], &n, &ny, &nx, &gradient, &b[3], &b[4], &b[5]))
        return NULL;
    PyObject *out = NULL;
    Py_ssize_t cells = n * ny * nx;
    if (check(&b[0], 8 * m * m, "coef") || check(&b[1], 8 * n, "x0") ||
        check(&b[2], 8 * n, "y0") || check(&b[3], 8 * cells, "v") ||
        (gradient && (check(&b[4], 8 * cells, "gx") || check(&b[5], 8 * cells, "gy"))))
        goto done;
    const double *coef = b[0].buf, *x0 = b[1].buf, *y0 = b[2].buf;
    double *v = b[3].buf, *gx = b[4].buf, *gy = b[5].buf;
    double scale = (double)per_px;
    for (Py_ssize_t k = 0; k < n; k++) {
        double ux = (x0[k] + radius) * scale + (double)pad;
        double uy = (y0[k] + radius) * scale + (double)pad;
        double fx = floor(ux), fy = floor(uy);
        double wx[4], dwx[4], wy[4], dwy[4];
        bspline_weights(ux - fx, wx, dwx);
        bspline_weights(uy - fy, wy, dwy);
        Py_ssize_t ix0 = (Py_ssize_t)fx - 1, iy0 = (Py_ssize_t)fy - 1;
        for (Py_ssize_t i = 0; i < ny; i++) {
            double dy = y0[k] + (double)i;
            Py_ssize_t iy = iy0 + per_px * i;
            int row_in = fabs(dy) < radius && iy >= 0 && iy + 3 < m;
            Py_ssize_t o = (k * ny + i) * nx;
            for (Py_ssize_t j = 0; j < nx; j++) {
                double dx = x0[k] + (double)j;
                Py_ssize_t ix = ix0 + per_px * j;
                if (!row_in || !(fabs(dx) < radius) || ix < 0 || ix + 3 >= m) {
                    v[o + j] = 0.0;
                    if (gradient) gx[o + j] = gy[o + j] = 0.0;
                    continue;
                }
                double val = 0.0, ddx = 0.0, ddy = 0.0;
                for (int p = 0; p < 4; p++) {
                    const double *c = coef + (iy + p) * m + ix;
                    double hx = wx[0] * c[0] + wx[1] * c[1] + wx[2] * c[2] + wx[3] * c[3];
                    val += wy[p] * hx;
                    if (gradient) {
                        double dh = dwx[0] * c[0] + dwx[1] * c[1] + dwx[2] * c[2] + dwx[3] * c[3];
                        ddx += wy[p] * dh;
                        ddy += dwy[p] * hx;
                    }
                }
                v[o + j] = val > 0.0 ? val : 0.0;
                if (gradient) {
                    gx[o + j] = ddx * scale;
                    gy[o + j] = ddy * scale;
                }
            }
        }
    }
    out = Py_NewRef(Py_None);
done:
    for (int i = 0; i < 6; i++)
        if (b[i].obj != NULL) PyBuffer_Release(&b[i]);
    return out;
}

static PyMethodDef methods[] = {
    {"static_gaussian", py_static_gaussian, METH_VARARGS,
     "Templates, fixed light and Jacobian of Gaussian stars at rest on their windows."},
    {"normal_equations", py_normal_equations, METH_VARARGS,
     "Per group: A, B, C, u, v of the normal equations."},
    {"table_grid", py_table_grid, METH_VARARGS,
     "A tabulated PSF's cubic B-spline on grids of whole pixels, and its gradient."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_modelc", NULL, -1, methods};

PyMODINIT_FUNC PyInit__modelc(void) { return PyModule_Create(&module); }
