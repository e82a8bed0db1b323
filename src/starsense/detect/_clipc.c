/* Compiled kernel of starsense.detect.clip: sigma clipping and MADs of sorted mesh boxes.
 *
 * The NumPy implementation in clip.py bisects every box at once, a few hundred small array
 * operations per frame whose cost is NumPy's per-call overhead, not the arithmetic. This
 * kernel runs the same algorithm box by box, with the same float32 and float64 operations in
 * the same order, so its results are those of clip.py bit for bit
 * (tests/detect/test_detect_clip_kernel.py). clip_rows, mad_masked and mad_resid sort each
 * box's samples themselves (an LSD radix sort on the values' bits, which orders them as
 * np.sort does: NaN last), in the cache, in place of NumPy's sort of the whole mesh and its
 * copies; mad_masked and mad_resid sort only the samples they keep, and mad_resid forms the
 * residuals about the level map (background.py) as it goes. gather reads a regular mesh's
 * integer samples out of the frame (background.py's _mesh_samples) and converts them.
 *
 * Built by setup.py as an optional extension: without a C compiler the package uses
 * clip.py's NumPy path. No NumPy headers: arrays arrive through the buffer protocol.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* Median of s[lo:lo+count] (float32 values averaged in float64); NaN if empty. */
static double ranked(const float *s, Py_ssize_t lo, Py_ssize_t count)
{
    if (count <= 0)
        return NAN;
    return 0.5 * ((double)s[lo + (count - 1) / 2] + (double)s[lo + count / 2]);
}

/* lo + how many of the ascending s[lo:hi] are < x (float64 comparison). */
static Py_ssize_t rank_less_d(const float *s, Py_ssize_t lo, Py_ssize_t hi, double x)
{
    while (lo < hi) {
        Py_ssize_t mid = lo + ((hi - lo) >> 1);
        if ((double)s[mid] < x)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* lo + how many of the ascending s[lo:hi] are < x (float32 comparison). */
static Py_ssize_t rank_less_f(const float *s, Py_ssize_t lo, Py_ssize_t hi, float x)
{
    while (lo < hi) {
        Py_ssize_t mid = lo + ((hi - lo) >> 1);
        if (s[mid] < x)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* k-th smallest (0-based) of the deviations of a sorted run about m: the n_below values
 * m - s[split - 1 - i] and the n_above values s[split + j] - m, each ascending (float32). */
static float kth_deviation(const float *s, Py_ssize_t split, float m, Py_ssize_t n_below,
                           Py_ssize_t n_above, Py_ssize_t k)
{
    Py_ssize_t lo = k + 1 - n_above > 0 ? k + 1 - n_above : 0; /* taken from below */
    Py_ssize_t hi = k + 1 < n_below ? k + 1 : n_below;
    while (lo < hi) {
        Py_ssize_t mid = lo + ((hi - lo) >> 1);
        float from_below = m - s[split - 1 - mid];
        float from_above = s[split + (k - mid)] - m;
        if (from_below >= from_above)
            hi = mid;
        else
            lo = mid + 1;
    }
    Py_ssize_t a = lo, b = k + 1 - lo;
    float best = -INFINITY;
    if (a > 0) {
        float v = m - s[split - a];
        if (v > best)
            best = v;
    }
    if (b > 0) {
        float v = s[split + b - 1] - m;
        if (v > best)
            best = v;
    }
    return best;
}

/* Median of |s[lo:hi] - float32(med)| (float32 deviations, averaged in float64); NaN if empty. */
static double run_mad(const float *s, Py_ssize_t lo, Py_ssize_t hi, double med)
{
    Py_ssize_t count = hi - lo;
    if (count <= 0)
        return NAN;
    float m = (float)med;
    Py_ssize_t split = rank_less_f(s, lo, hi, m);
    Py_ssize_t n_below = split - lo, n_above = hi - split;
    float a = kth_deviation(s, split, m, n_below, n_above, (count - 1) / 2);
    float b = kth_deviation(s, split, m, n_below, n_above, count / 2);
    return 0.5 * ((double)a + (double)b);
}

static Py_ssize_t finite_count(const float *s, Py_ssize_t m)
{
    Py_ssize_t n = 0;
    for (Py_ssize_t i = 0; i < m; i++)
        n += isfinite(s[i]) ? 1 : 0;
    return n;
}

/* Sigma-clip one sorted row of m values (NaN last): its clipped median, lowest and highest
 * kept values and how many were kept (clip.py's _clip_sorted_numpy, one box). */
static void clip_row(const float *s, Py_ssize_t m, double sigma, double mad_to_sigma,
                     int iterations, double *med_out, float *low_out, float *high_out,
                     int64_t *kept_out)
{
    Py_ssize_t lo = 0, hi = finite_count(s, m);
    double med = ranked(s, lo, hi - lo);
    for (int it = 0; it < iterations; it++) {
        double scale = mad_to_sigma * run_mad(s, lo, hi, med);
        double half = scale > 0 ? sigma * scale : INFINITY;
        Py_ssize_t new_lo = rank_less_d(s, lo, hi, med - half);
        Py_ssize_t new_hi = rank_less_d(s, lo, hi, nextafter(med + half, INFINITY));
        if (new_hi < new_lo)
            new_hi = new_lo;
        if (new_lo == lo && new_hi == hi)
            break;
        lo = new_lo;
        hi = new_hi;
        med = ranked(s, lo, hi - lo);
    }
    *med_out = med;
    *low_out = s[lo < m - 1 ? lo : m - 1];
    *high_out = s[hi - 1 > 0 ? hi - 1 : 0];
    *kept_out = (int64_t)(hi - lo);
}

/* ---------------------------------------------------------------------------------------- */
/* Sorting a row: the values as unsigned keys of the same order, an LSD radix sort on those.  */

/* A float's bits as an unsigned key of its order; every NaN the largest key (np.sort puts
 * NaN last). -0.0 sorts just below +0.0: they compare equal, so either order is sorted. */
static inline uint32_t float_key(float f)
{
    uint32_t u;
    if (f != f)
        return UINT32_MAX;
    memcpy(&u, &f, 4);
    return u ^ ((uint32_t)((int32_t)u >> 31) | 0x80000000u); /* no branch on the sign */
}

static inline float key_float(uint32_t k)
{
    uint32_t u = (k & 0x80000000u) ? (k & 0x7fffffffu) : ~k; /* UINT32_MAX: a NaN */
    float f;
    memcpy(&f, &u, 4);
    return f;
}

/* Sort n keys ascending by their low ``bytes`` bytes (one byte per pass, a pass skipped where
 * every key has the same byte); ``tmp``: n scratch keys. */
static void radix_sort(uint32_t *keys, uint32_t *tmp, Py_ssize_t n, int bytes)
{
    uint32_t hist[4][256];
    memset(hist, 0, sizeof(hist));
    for (Py_ssize_t i = 0; i < n; i++) {
        uint32_t k = keys[i];
        for (int b = 0; b < bytes; b++)
            hist[b][(k >> (8 * b)) & 255u]++;
    }
    uint32_t *src = keys, *dst = tmp;
    for (int b = 0; b < bytes; b++) {
        uint32_t *h = hist[b], total = 0;
        int trivial = 0;
        for (int v = 0; v < 256; v++) {
            if (h[v] == (uint32_t)n)
                trivial = 1;
            uint32_t c = h[v];
            h[v] = total;
            total += c;
        }
        if (trivial)
            continue;
        for (Py_ssize_t i = 0; i < n; i++) {
            uint32_t k = src[i];
            dst[h[(k >> (8 * b)) & 255u]++] = k;
        }
        uint32_t *t = src;
        src = dst;
        dst = t;
    }
    if (src != keys)
        memcpy(keys, src, (size_t)n * sizeof(uint32_t));
}

/* Row r of ``values`` (m samples of the type ``kind``: 'f' float32, 'B'/'b' 8-bit, 'H'/'h'
 * 16-bit unsigned/signed integers) sorted ascending into s as float32 (NaN last). */
static void sort_row(const void *values, char kind, Py_ssize_t r, Py_ssize_t m, float *s,
                     uint32_t *keys, uint32_t *tmp)
{
    Py_ssize_t i;
    int bytes = 4;
    switch (kind) {
    case 'B':
        for (i = 0, bytes = 1; i < m; i++)
            keys[i] = ((const uint8_t *)values)[r * m + i];
        break;
    case 'b':
        for (i = 0, bytes = 1; i < m; i++)
            keys[i] = (uint8_t)((const int8_t *)values)[r * m + i] ^ 0x80u;
        break;
    case 'H':
        for (i = 0, bytes = 2; i < m; i++)
            keys[i] = ((const uint16_t *)values)[r * m + i];
        break;
    case 'h':
        for (i = 0, bytes = 2; i < m; i++)
            keys[i] = (uint16_t)((const int16_t *)values)[r * m + i] ^ 0x8000u;
        break;
    default:
        for (i = 0; i < m; i++)
            keys[i] = float_key(((const float *)values)[r * m + i]);
    }
    radix_sort(keys, tmp, m, bytes);
    switch (kind) {
    case 'B':
    case 'H':
        for (i = 0; i < m; i++)
            s[i] = (float)keys[i];
        break;
    case 'b':
        for (i = 0; i < m; i++)
            s[i] = (float)(int8_t)(uint8_t)(keys[i] ^ 0x80u);
        break;
    case 'h':
        for (i = 0; i < m; i++)
            s[i] = (float)(int16_t)(uint16_t)(keys[i] ^ 0x8000u);
        break;
    default:
        for (i = 0; i < m; i++)
            s[i] = key_float(keys[i]);
    }
}

static int check(Py_buffer *b, Py_ssize_t bytes, const char *what)
{
    if (b->len != bytes) {
        PyErr_Format(PyExc_ValueError, "%s has %zd bytes, expected %zd", what, b->len, bytes);
        return -1;
    }
    return 0;
}

/* clip_sorted(sorted, rows, m, sigma, mad_to_sigma, iterations, med, low, high, kept):
 * mad_to_sigma is clip.py's MAD_TO_SIGMA (its one copy). */
static PyObject *clip_sorted(PyObject *self, PyObject *args)
{
    Py_buffer sb, medb, lowb, highb, keptb;
    Py_ssize_t rows, m;
    double sigma, mad_to_sigma;
    int iterations;
    if (!PyArg_ParseTuple(args, "y*nnddiw*w*w*w*", &sb, &rows, &m, &sigma, &mad_to_sigma,
                          &iterations, &medb, &lowb, &highb, &keptb))
        return NULL;
    PyObject *result = NULL;
    if (rows < 0 || m < 1 || check(&sb, rows * m * 4, "sorted") || check(&medb, rows * 8, "med")
        || check(&lowb, rows * 4, "low") || check(&highb, rows * 4, "high")
        || check(&keptb, rows * 8, "kept")) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "bad shape");
        goto done;
    }
    const float *all = (const float *)sb.buf;
    double *med_out = (double *)medb.buf;
    float *low_out = (float *)lowb.buf, *high_out = (float *)highb.buf;
    int64_t *kept_out = (int64_t *)keptb.buf;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t r = 0; r < rows; r++)
        clip_row(all + r * m, m, sigma, mad_to_sigma, iterations, med_out + r, low_out + r,
                 high_out + r, kept_out + r);
    Py_END_ALLOW_THREADS
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&sb);
    PyBuffer_Release(&medb);
    PyBuffer_Release(&lowb);
    PyBuffer_Release(&highb);
    PyBuffer_Release(&keptb);
    return result;
}

/* mad_sorted(sorted, rows, m, n, out): the MAD of each row's first n[r] values. */
static PyObject *mad_sorted(PyObject *self, PyObject *args)
{
    Py_buffer sb, nb, outb;
    Py_ssize_t rows, m;
    if (!PyArg_ParseTuple(args, "y*nny*w*", &sb, &rows, &m, &nb, &outb))
        return NULL;
    PyObject *result = NULL;
    if (rows < 0 || m < 1 || check(&sb, rows * m * 4, "sorted") || check(&nb, rows * 8, "n")
        || check(&outb, rows * 8, "out")) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "bad shape");
        goto done;
    }
    const float *all = (const float *)sb.buf;
    const int64_t *n = (const int64_t *)nb.buf;
    double *out = (double *)outb.buf;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t r = 0; r < rows; r++) {
        const float *s = all + r * m;
        Py_ssize_t count = (Py_ssize_t)n[r];
        if (count > m)
            count = m;
        out[r] = run_mad(s, 0, count, ranked(s, 0, count));
    }
    Py_END_ALLOW_THREADS
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&sb);
    PyBuffer_Release(&nb);
    PyBuffer_Release(&outb);
    return result;
}

/* clip_rows(values, kind, rows, m, sigma, mad_to_sigma, iterations, med, low, high, kept):
 * clip_sorted on the rows of ``values`` (unsorted; kind as sort_row's), each sorted here. */
static PyObject *clip_rows(PyObject *self, PyObject *args)
{
    Py_buffer vb, medb, lowb, highb, keptb;
    Py_ssize_t rows, m;
    double sigma, mad_to_sigma;
    int iterations, kind;
    if (!PyArg_ParseTuple(args, "y*Cnnddiw*w*w*w*", &vb, &kind, &rows, &m, &sigma, &mad_to_sigma,
                          &iterations, &medb, &lowb, &highb, &keptb))
        return NULL;
    PyObject *result = NULL;
    Py_ssize_t item = kind == 'f' ? 4 : (kind == 'H' || kind == 'h' ? 2 : 1);
    if (kind != 'f' && kind != 'B' && kind != 'b' && kind != 'H' && kind != 'h') {
        PyErr_Format(PyExc_ValueError, "kind %c is not one of f, B, b, H, h", kind);
        goto done;
    }
    if (rows < 0 || m < 1 || check(&vb, rows * m * item, "values")
        || check(&medb, rows * 8, "med") || check(&lowb, rows * 4, "low")
        || check(&highb, rows * 4, "high") || check(&keptb, rows * 8, "kept")) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "bad shape");
        goto done;
    }
    float *s = malloc((size_t)m * sizeof(float));
    uint32_t *keys = malloc((size_t)m * 2 * sizeof(uint32_t));
    if (s == NULL || keys == NULL) {
        free(s);
        free(keys);
        PyErr_NoMemory();
        goto done;
    }
    double *med_out = (double *)medb.buf;
    float *low_out = (float *)lowb.buf, *high_out = (float *)highb.buf;
    int64_t *kept_out = (int64_t *)keptb.buf;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t r = 0; r < rows; r++) {
        sort_row(vb.buf, (char)kind, r, m, s, keys, keys + m);
        clip_row(s, m, sigma, mad_to_sigma, iterations, med_out + r, low_out + r, high_out + r,
                 kept_out + r);
    }
    Py_END_ALLOW_THREADS
    free(s);
    free(keys);
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&vb);
    PyBuffer_Release(&medb);
    PyBuffer_Release(&lowb);
    PyBuffer_Release(&highb);
    PyBuffer_Release(&keptb);
    return result;
}

/* The first n of the row sorted after its samples not kept were set to +inf (robust_sigma's
 * NumPy form): the n_kept kept samples that are not NaN ascending, then as many of the
 * (m - n) infinities as there were kept NaNs, then the remaining NaNs. */
static Py_ssize_t kept_sorted(const float *v, const uint8_t *keep, Py_ssize_t m, float *s,
                              uint32_t *keys, uint32_t *tmp)
{
    Py_ssize_t n = 0, n_nan = 0, q = 0;
    for (Py_ssize_t i = 0; i < m; i++) {
        if (!keep[i])
            continue;
        n++;
        float f = v[i];
        if (f != f)
            n_nan++;
        else
            keys[q++] = float_key(f);
    }
    radix_sort(keys, tmp, q, 4);
    for (Py_ssize_t i = 0; i < q; i++)
        s[i] = key_float(keys[i]);
    Py_ssize_t infs = n_nan < m - n ? n_nan : m - n;
    for (Py_ssize_t i = 0; i < n_nan; i++)
        s[q + i] = i < infs ? INFINITY : NAN;
    return n;
}

/* mad_masked(values, keep, rows, m, out): the MAD of each row's samples where keep (uint8) is
 * set, as mad_sorted gives it on the row sorted with the others set to +inf. */
static PyObject *mad_masked(PyObject *self, PyObject *args)
{
    Py_buffer vb, kb, outb;
    Py_ssize_t rows, m;
    if (!PyArg_ParseTuple(args, "y*y*nnw*", &vb, &kb, &rows, &m, &outb))
        return NULL;
    PyObject *result = NULL;
    if (rows < 0 || m < 1 || check(&vb, rows * m * 4, "values") || check(&kb, rows * m, "keep")
        || check(&outb, rows * 8, "out")) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "bad shape");
        goto done;
    }
    float *s = malloc((size_t)m * sizeof(float));
    uint32_t *keys = malloc((size_t)m * 2 * sizeof(uint32_t));
    if (s == NULL || keys == NULL) {
        free(s);
        free(keys);
        PyErr_NoMemory();
        goto done;
    }
    const float *all = (const float *)vb.buf;
    const uint8_t *keep = (const uint8_t *)kb.buf;
    double *out = (double *)outb.buf;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t r = 0; r < rows; r++) {
        Py_ssize_t n = kept_sorted(all + r * m, keep + r * m, m, s, keys, keys + m);
        out[r] = run_mad(s, 0, n, ranked(s, 0, n));
    }
    Py_END_ALLOW_THREADS
    free(s);
    free(keys);
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&vb);
    PyBuffer_Release(&kb);
    PyBuffer_Release(&outb);
    return result;
}

/* mad_resid(cells, level, cols, ny, nx, my, mx, every, low, high, out): mad_masked of the
 * mesh's residuals: box (by, bx) of the regular mesh holds the samples cells[by, bx, i mx + j]
 * of the pixels ((by my + i) every, (bx mx + j) every); a sample is kept where low <= cell
 * <= high (its box's clipping bounds, float32) and its residual is cell - level at its pixel
 * (float32): background.py's keep mask, gathered level and subtraction, without their arrays. */
static PyObject *mad_resid(PyObject *self, PyObject *args)
{
    Py_buffer cb, lb, lowb, highb, outb;
    Py_ssize_t cols, ny, nx, my, mx, every;
    if (!PyArg_ParseTuple(args, "y*y*nnnnnny*y*w*", &cb, &lb, &cols, &ny, &nx, &my, &mx, &every,
                          &lowb, &highb, &outb))
        return NULL;
    PyObject *result = NULL;
    Py_ssize_t rows = ny * nx, m = my * mx;
    Py_ssize_t last_row = (ny * my - 1) * every, last_col = (nx * mx - 1) * every;
    if (rows < 1 || m < 1 || every < 1 || cols <= last_col || check(&cb, rows * m * 4, "cells")
        || lb.len < (last_row * cols + last_col + 1) * 4 || check(&lowb, rows * 4, "low")
        || check(&highb, rows * 4, "high") || check(&outb, rows * 8, "out")) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "bad shape");
        goto done;
    }
    float *buf = malloc((size_t)m * 2 * sizeof(float));
    uint32_t *keys = malloc((size_t)m * 2 * sizeof(uint32_t));
    uint8_t *keep = malloc((size_t)m);
    if (buf == NULL || keys == NULL || keep == NULL) {
        free(buf);
        free(keys);
        free(keep);
        PyErr_NoMemory();
        goto done;
    }
    const float *cells = (const float *)cb.buf, *level = (const float *)lb.buf;
    const float *low = (const float *)lowb.buf, *high = (const float *)highb.buf;
    double *out = (double *)outb.buf;
    float *v = buf, *s = buf + m;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t by = 0; by < ny; by++)
        for (Py_ssize_t bx = 0; bx < nx; bx++) {
            Py_ssize_t row = by * nx + bx;
            const float *c = cells + row * m;
            float lo = low[row], hi = high[row];
            for (Py_ssize_t i = 0; i < my; i++) {
                const float *lev = level + (by * my + i) * every * cols + bx * mx * every;
                for (Py_ssize_t j = 0; j < mx; j++) {
                    float x = c[i * mx + j];
                    keep[i * mx + j] = x >= lo && x <= hi;
                    v[i * mx + j] = x - lev[j * every];
                }
            }
            Py_ssize_t n = kept_sorted(v, keep, m, s, keys, keys + m);
            out[row] = run_mad(s, 0, n, ranked(s, 0, n));
        }
    Py_END_ALLOW_THREADS
    free(buf);
    free(keys);
    free(keep);
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&cb);
    PyBuffer_Release(&lb);
    PyBuffer_Release(&lowb);
    PyBuffer_Release(&highb);
    PyBuffer_Release(&outb);
    return result;
}

/* gather(a, kind, cols, ny, nx, my, mx, every, counts, cells): the samples of the regular mesh
 * (mesh.py's MeshSampler.gather): counts[by, bx, i mx + j] = a[(by my + i) every,
 * (bx mx + j) every] as the frame's 8/16-bit integers (kind 'B', 'b', 'H', 'h'), cells the
 * same as float32 (exact), in one pass. */
#define GATHER_SAMPLES(T)                                                                      \
    for (Py_ssize_t by = 0; by < ny; by++)                                                     \
        for (Py_ssize_t bx = 0; bx < nx; bx++) {                                               \
            Py_ssize_t at = (by * nx + bx) * my * mx;                                          \
            for (Py_ssize_t i = 0; i < my; i++) {                                              \
                const T *src = (const T *)ab.buf + (by * my + i) * every * cols + bx * mx * every; \
                T *dst = (T *)cb.buf + at + i * mx;                                            \
                float *f = (float *)fb.buf + at + i * mx;                                      \
                for (Py_ssize_t j = 0; j < mx; j++) {                                          \
                    T v = src[j * every];                                                      \
                    dst[j] = v;                                                                \
                    f[j] = (float)v;                                                           \
                }                                                                              \
            }                                                                                  \
        }

static PyObject *gather(PyObject *self, PyObject *args)
{
    Py_buffer ab, cb, fb;
    int kind;
    Py_ssize_t cols, ny, nx, my, mx, every;
    if (!PyArg_ParseTuple(args, "y*Cnnnnnnw*w*", &ab, &kind, &cols, &ny, &nx, &my, &mx, &every,
                          &cb, &fb))
        return NULL;
    PyObject *result = NULL;
    Py_ssize_t item = (kind == 'H' || kind == 'h') ? 2 : 1, n = ny * nx * my * mx;
    Py_ssize_t last_row = (ny * my - 1) * every, last_col = (nx * mx - 1) * every;
    if (kind != 'B' && kind != 'b' && kind != 'H' && kind != 'h') {
        PyErr_Format(PyExc_ValueError, "kind %c is not one of B, b, H, h", kind);
        goto done;
    }
    if (n < 1 || every < 1 || cols <= last_col || ab.len < (last_row * cols + last_col + 1) * item
        || check(&cb, n * item, "counts") || check(&fb, n * 4, "cells")) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "bad shape");
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    switch (kind) {
    case 'B':
        GATHER_SAMPLES(uint8_t)
        break;
    case 'b':
        GATHER_SAMPLES(int8_t)
        break;
    case 'H':
        GATHER_SAMPLES(uint16_t)
        break;
    default:
        GATHER_SAMPLES(int16_t)
    }
    Py_END_ALLOW_THREADS
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&ab);
    PyBuffer_Release(&cb);
    PyBuffer_Release(&fb);
    return result;
}

static PyMethodDef methods[] = {
    {"clip_sorted", clip_sorted, METH_VARARGS, "Sigma-clip the sorted rows (see clip.py)."},
    {"mad_sorted", mad_sorted, METH_VARARGS, "MAD of the sorted rows' first n values."},
    {"clip_rows", clip_rows, METH_VARARGS, "Sort each row, then clip it as clip_sorted."},
    {"mad_masked", mad_masked, METH_VARARGS, "MAD of each row's kept samples."},
    {"gather", gather, METH_VARARGS, "The regular mesh's integer samples and their floats."},
    {"mad_resid", mad_resid, METH_VARARGS, "MAD of the mesh's kept residuals (background.py)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_clipc", NULL, -1, methods};

PyMODINIT_FUNC PyInit__clipc(void) { return PyModule_Create(&module); }
