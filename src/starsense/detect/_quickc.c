/* Compiled kernels of quick extraction (quick.py): the clipped box statistics of the coarse
 * background, and the one pass that subtracts the interpolated level and finds the lit pixels.
 *
 *   box_stats       quick.py's _clipped_stats: per box, its samples (rows ``ri`` x columns
 *                   ``ci`` where valid, MeshSampler's indices); their mean and standard deviation (n - 1),
 *                   clipped at ``clip`` standard deviations about the mean until nothing more
 *                   is clipped (at most ``max_iter`` times). float64 sums of the deviations
 *                   from the box's middle sample, updated as samples leave or return (NumPy
 *                   sums pairwise, in two passes: equal to within rounding). Returns the
 *                   lowest sample and how many samples have that value;
 *   subtract_above  quick.py's quick_subtract: per row, the level and noise meshes
 *                   interpolated between the box rows (float64), then along the row between
 *                   the box columns (w0 * v0 + w1 * v1, in that order: float32 for the level,
 *                   float64 for the noise); sub = (float)a - level in float32;
 *                   a pixel is lit when sub > (float)max(k * clip(noise, lo, hi), floor). The
 *                   noise is interpolated only where sub exceeds the lowest threshold anywhere,
 *                   (float)max(k * lo, floor): below it no pixel can be lit. The same frame and
 *                   lit pixels as the NumPy form, bit for bit.
 *
 * Built by setup.py as an optional extension (no fused multiply-adds); without a C compiler
 * the package runs the NumPy forms. No NumPy headers: arrays arrive through the buffer protocol.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static int check(Py_buffer *b, Py_ssize_t bytes, const char *name)
{
    if (b->len < bytes) {
        PyErr_Format(PyExc_ValueError, "%s: buffer of %zd bytes, %zd needed", name, b->len,
                     bytes);
        return -1;
    }
    return 0;
}

static Py_ssize_t item_size(int kind)
{
    switch (kind) {
    case 'B': return 1;
    case 'H': case 'h': return 2;
    case 'f': return 4;
    case 'd': return 8;
    default: return 0;
    }
}

/* ---------------------------------------------------------------------------------------- */
/* box_stats(a, kind, cols, ny, nx, my, mx, every, clip, max_iter, mean, sd, n)              */

static void clipped(const double *x, unsigned char *keep, unsigned char *next, Py_ssize_t m,
                    double clip, int max_iter, double *mean_out, double *sd_out, int64_t *n_out)
{
    /* sums of the deviations from one sample (no cancellation for values far from zero),
     * updated as samples leave or return */
    double ref = x[m / 2], s1 = 0.0, s2 = 0.0, mean = NAN, sd = NAN;
    int64_t n = m;
    for (Py_ssize_t j = 0; j < m; j++) {
        double d = x[j] - ref;
        s1 += d;
        s2 += d * d;
        keep[j] = 1;
    }
    for (int it = 0; it < max_iter; it++) {
        double md = s1 / (double)n;
        mean = ref + md;
        sd = sqrt(fmax(s2 - s1 * md, 0.0) / (double)(n - 1));
        if (n < 2)
            break;
        double bound = clip * sd;
        int changed = 0;
        for (Py_ssize_t j = 0; j < m; j++) {
            next[j] = fabs(x[j] - mean) <= bound;
            changed |= next[j] != keep[j];
        }
        if (!changed)
            break;
        for (Py_ssize_t j = 0; j < m; j++) {
            if (next[j] == keep[j])
                continue;
            double d = x[j] - ref, sign = next[j] ? 1.0 : -1.0;
            s1 += sign * d;
            s2 += sign * d * d;
            n += next[j] ? 1 : -1;
            keep[j] = next[j];
        }
    }
    *mean_out = mean;
    *sd_out = sd;
    *n_out = n;
}

#define GATHER(T)                                                                          \
    do {                                                                                       \
        const T *in = (const T *)ab.buf;                                                       \
        for (Py_ssize_t u = 0; u < my; u++) {                                                  \
            if (!rv[by * my + u])                                                              \
                continue;                                                                      \
            const T *row = in + ri[by * my + u] * cols;                                        \
            for (Py_ssize_t v = 0; v < mx; v++)                                                \
                if (cv[bx * mx + v])                                                           \
                    x[k++] = (double)row[ci[bx * mx + v]];                                     \
        }                                                                                      \
    } while (0)

static PyObject *box_stats(PyObject *self, PyObject *args)
{
    Py_buffer ab, rib, rvb, cib, cvb, mb, sb, nb;
    int kind, max_iter;
    Py_ssize_t rows, cols, ny, nx, my, mx;
    double clip;
    if (!PyArg_ParseTuple(args, "y*Cnny*y*y*y*nnnndiw*w*w*", &ab, &kind, &rows, &cols, &rib,
                          &rvb, &cib, &cvb, &ny, &nx, &my, &mx, &clip, &max_iter, &mb, &sb,
                          &nb))
        return NULL;
    PyObject *result = NULL;
    double *x = NULL;
    unsigned char *keep = NULL;
    Py_ssize_t item = item_size(kind), m = my * mx;
    if (item == 0 || rows < 1 || cols < 1 || ny < 1 || nx < 1 || my < 1 || mx < 1
        || max_iter < 1) {
        PyErr_SetString(PyExc_ValueError, "bad kind or mesh geometry");
        goto done;
    }
    if (check(&ab, rows * cols * item, "a") || check(&rib, ny * my * 8, "ri")
        || check(&rvb, ny * my, "rvalid") || check(&cib, nx * mx * 8, "ci")
        || check(&cvb, nx * mx, "cvalid") || check(&mb, ny * nx * 8, "mean")
        || check(&sb, ny * nx * 8, "sd") || check(&nb, ny * nx * 8, "n"))
        goto done;
    const int64_t *ri = rib.buf, *ci = cib.buf;
    const unsigned char *rv = rvb.buf, *cv = cvb.buf;
    for (Py_ssize_t j = 0; j < ny * my; j++)
        if (ri[j] < 0 || ri[j] >= rows) {
            PyErr_SetString(PyExc_ValueError, "ri outside the frame");
            goto done;
        }
    for (Py_ssize_t j = 0; j < nx * mx; j++)
        if (ci[j] < 0 || ci[j] >= cols) {
            PyErr_SetString(PyExc_ValueError, "ci outside the frame");
            goto done;
        }
    x = malloc(m * sizeof(double));
    keep = malloc(2 * m);
    if (x == NULL || keep == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    double lowest = INFINITY;
    Py_ssize_t at_lowest = 0;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t by = 0; by < ny; by++)
        for (Py_ssize_t bx = 0; bx < nx; bx++) {
            Py_ssize_t k = 0;
            switch (kind) { /* one loop per sample type */
            case 'B': GATHER(uint8_t); break;
            case 'H': GATHER(uint16_t); break;
            case 'h': GATHER(int16_t); break;
            case 'f': GATHER(float); break;
            default: GATHER(double); break;
            }
            for (Py_ssize_t j = 0; j < k; j++) {
                if (x[j] < lowest) {
                    lowest = x[j];
                    at_lowest = 0;
                }
                at_lowest += x[j] == lowest;
            }
            Py_ssize_t b = by * nx + bx;
            if (k == 0) {
                ((double *)mb.buf)[b] = ((double *)sb.buf)[b] = NAN;
                ((int64_t *)nb.buf)[b] = 0;
                continue;
            }
            clipped(x, keep, keep + k, k, clip, max_iter, (double *)mb.buf + b,
                    (double *)sb.buf + b, (int64_t *)nb.buf + b);
        }
    Py_END_ALLOW_THREADS
    result = Py_BuildValue("dn", lowest, at_lowest);
done:
    free(x);
    free(keep);
    PyBuffer_Release(&ab);
    PyBuffer_Release(&rib);
    PyBuffer_Release(&rvb);
    PyBuffer_Release(&cib);
    PyBuffer_Release(&cvb);
    PyBuffer_Release(&mb);
    PyBuffer_Release(&sb);
    PyBuffer_Release(&nb);
    return result;
}

/* ---------------------------------------------------------------------------------------- */
/* subtract_above(a, kind, rows, cols, level, noise, ny, nx, sy, wy0, wy1, sx, wx0, wx1,      */
/*                lo, hi, k, floor, sub, idx, noise_out, cap) -> count                         */

typedef struct {
    const void *a;
    int kind;
    Py_ssize_t rows, cols, ny, nx;
    const double *level, *noise, *wy0, *wy1, *wx0, *wx1;
    const float *wx0f, *wx1f;
    const int64_t *sy, *sx;
    double lo, hi, k, floor;
    float *sub;
    int64_t *idx;
    float *noise_out;
    Py_ssize_t cap;
} Pass;

static inline double lerp_at(const double *row, Py_ssize_t nx, const Pass *p, Py_ssize_t c)
{
    Py_ssize_t i0 = (Py_ssize_t)p->sx[c], i1 = i0 + 1 < nx ? i0 + 1 : nx - 1;
    return p->wx0[c] * row[i0] + p->wx1[c] * row[i1];
}

/* one run of columns [c0, c1) between two box centres of row ``base``: the level (float32),
 * the frame minus it into ``out``; whether any exceeds ``lowest`` */
#define SUBTRACT_RUN(T)                                                                    \
    do {                                                                                       \
        const T *in = (const T *)p->a + base;                                                  \
        for (Py_ssize_t c = c0; c < c1; c++) {                                                 \
            float o = (float)in[c] - (p->wx0f[c] * v0 + p->wx1f[c] * v1);                      \
            out[c] = o;                                                                        \
            any |= o > lowest;                                                                 \
        }                                                                                      \
    } while (0)

/* the lit pixels among columns [c0, c1) of a row */
static Py_ssize_t lit_in_run(const Pass *p, const float *out, const double *nr, Py_ssize_t base,
                             Py_ssize_t c0, Py_ssize_t c1, float lowest, Py_ssize_t count)
{
    for (Py_ssize_t c = c0; c < c1; c++) {
        if (!(out[c] > lowest))
            continue;
        double nz = lerp_at(nr, p->nx, p, c);
        nz = fmin(fmax(nz, p->lo), p->hi);
        float thr = (float)fmax(p->k * nz, p->floor);
        if (out[c] > thr) {
            if (count < p->cap) {
                p->idx[count] = base + c;
                p->noise_out[count] = (float)nz;
            }
            count++;
        }
    }
    return count;
}

/* AVX2 where the processor has it (8 floats at a time; the same IEEE roundings, no fused
 * multiply-adds), SSE2 elsewhere: the loader picks the clone */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target_clones("avx2", "default")))
#endif
static Py_ssize_t subtract_pass(const Pass *p, double *lr, double *nr)
{
    Py_ssize_t count = 0, nx = p->nx, cols = p->cols;
    float frame_lowest = (float)fmax(p->k * p->lo, p->floor);
    for (Py_ssize_t r = 0; r < p->rows; r++) {
        Py_ssize_t j0 = (Py_ssize_t)p->sy[r], j1 = j0 + 1 < p->ny ? j0 + 1 : p->ny - 1;
        for (Py_ssize_t i = 0; i < nx; i++) {
            lr[i] = p->wy0[r] * p->level[j0 * nx + i] + p->wy1[r] * p->level[j1 * nx + i];
            nr[i] = p->wy0[r] * p->noise[j0 * nx + i] + p->wy1[r] * p->noise[j1 * nx + i];
        }
        /* no pixel of the row has a threshold below the row's lowest noise: the noise along
         * the row is piecewise linear, least at a box centre or an end (less a margin for
         * the rounding of its interpolation), and clipped to [lo, hi] like each pixel's */
        double least = fmin(lerp_at(nr, nx, p, 0), lerp_at(nr, nx, p, cols - 1));
        for (Py_ssize_t i = 0; i < nx; i++)
            least = fmin(least, nr[i]);
        least = fmin(fmax(least - 1e-9 * fabs(least), p->lo), p->hi);
        float lowest = (float)fmax(p->k * least, p->floor);
        lowest = lowest > frame_lowest ? lowest : frame_lowest;
        Py_ssize_t base = r * cols;
        float *out = p->sub + base;
        /* one run of columns between two box centres at a time */
        for (Py_ssize_t c0 = 0; c0 < cols;) {
            Py_ssize_t i0 = (Py_ssize_t)p->sx[c0], i1 = i0 + 1 < nx ? i0 + 1 : nx - 1, c1 = c0;
            while (c1 < cols && p->sx[c1] == p->sx[c0])
                c1++;
            float v0 = (float)lr[i0], v1 = (float)lr[i1];
            int any = 0;
            switch (p->kind) { /* one loop per sample type, which the compiler vectorises */
            case 'B': SUBTRACT_RUN(uint8_t); break;
            case 'H': SUBTRACT_RUN(uint16_t); break;
            case 'h': SUBTRACT_RUN(int16_t); break;
            case 'f': SUBTRACT_RUN(float); break;
            default: SUBTRACT_RUN(double); break;
            }
            if (any)
                count = lit_in_run(p, out, nr, base, c0, c1, lowest, count);
            c0 = c1;
        }
    }
    return count;
}

static PyObject *subtract_above(PyObject *self, PyObject *args)
{
    Py_buffer ab, lb, nb, syb, wy0b, wy1b, sxb, wx0b, wx1b, sb, ib, ob;
    Pass p;
    if (!PyArg_ParseTuple(args, "y*Cnny*y*nny*y*y*y*y*y*ddddw*w*w*n", &ab, &p.kind, &p.rows,
                          &p.cols, &lb, &nb, &p.ny, &p.nx, &syb, &wy0b, &wy1b, &sxb, &wx0b,
                          &wx1b, &p.lo, &p.hi, &p.k, &p.floor, &sb, &ib, &ob, &p.cap))
        return NULL;
    PyObject *result = NULL;
    Py_ssize_t item = item_size(p.kind), n = p.rows * p.cols, m = p.ny * p.nx;
    if (item == 0 || p.rows < 1 || p.cols < 1 || p.ny < 1 || p.nx < 1 || p.cap < 0) {
        PyErr_SetString(PyExc_ValueError, "bad kind or geometry");
        goto done;
    }
    if (check(&ab, n * item, "a") || check(&lb, m * 8, "level") || check(&nb, m * 8, "noise")
        || check(&syb, p.rows * 8, "sy") || check(&wy0b, p.rows * 8, "wy0")
        || check(&wy1b, p.rows * 8, "wy1") || check(&sxb, p.cols * 8, "sx")
        || check(&wx0b, p.cols * 8, "wx0") || check(&wx1b, p.cols * 8, "wx1")
        || check(&sb, n * 4, "sub") || check(&ib, p.cap * 8, "idx")
        || check(&ob, p.cap * 4, "noise_out"))
        goto done;
    const int64_t *sy = syb.buf, *sx = sxb.buf;
    for (Py_ssize_t r = 0; r < p.rows; r++)
        if (sy[r] < 0 || sy[r] >= p.ny) {
            PyErr_SetString(PyExc_ValueError, "sy out of the mesh");
            goto done;
        }
    for (Py_ssize_t c = 0; c < p.cols; c++)
        if (sx[c] < 0 || sx[c] >= p.nx || (c > 0 && sx[c] < sx[c - 1])) {
            PyErr_SetString(PyExc_ValueError, "sx out of the mesh or not ascending");
            goto done;
        }
    p.a = ab.buf;
    p.level = lb.buf;
    p.noise = nb.buf;
    p.sy = sy;
    p.sx = sx;
    p.wy0 = wy0b.buf;
    p.wy1 = wy1b.buf;
    p.wx0 = wx0b.buf;
    p.wx1 = wx1b.buf;
    p.sub = sb.buf;
    p.idx = ib.buf;
    p.noise_out = ob.buf;
    double *buf = malloc(2 * p.nx * sizeof(double));
    float *fbuf = malloc(2 * p.cols * sizeof(float));
    if (buf == NULL || fbuf == NULL) {
        free(buf);
        free(fbuf);
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t c = 0; c < p.cols; c++) {
        fbuf[c] = (float)p.wx0[c];
        fbuf[p.cols + c] = (float)p.wx1[c];
    }
    p.wx0f = fbuf;
    p.wx1f = fbuf + p.cols;
    Py_ssize_t count;
    Py_BEGIN_ALLOW_THREADS
    count = subtract_pass(&p, buf, buf + p.nx);
    Py_END_ALLOW_THREADS
    free(buf);
    free(fbuf);
    result = PyLong_FromSsize_t(count);
done:
    PyBuffer_Release(&ab);
    PyBuffer_Release(&lb);
    PyBuffer_Release(&nb);
    PyBuffer_Release(&syb);
    PyBuffer_Release(&wy0b);
    PyBuffer_Release(&wy1b);
    PyBuffer_Release(&sxb);
    PyBuffer_Release(&wx0b);
    PyBuffer_Release(&wx1b);
    PyBuffer_Release(&sb);
    PyBuffer_Release(&ib);
    PyBuffer_Release(&ob);
    return result;
}

static PyMethodDef methods[] = {
    {"box_stats", box_stats, METH_VARARGS, "Clipped mean and std of each mesh box (quick.py)."},
    {"subtract_above", subtract_above, METH_VARARGS,
     "Frame minus the interpolated level, and the lit pixels (quick.py)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_quickc", NULL, -1, methods};

PyMODINIT_FUNC PyInit__quickc(void) { return PyModule_Create(&module); }
