/* Compiled kernel of starsense.detect.clip: sigma clipping and MADs of sorted mesh boxes.
 *
 * The NumPy implementation in clip.py bisects every box at once, a few hundred small array
 * operations per frame whose cost is NumPy's per-call overhead, not the arithmetic. This
 * kernel runs the same algorithm box by box on the same sorted rows (the sort stays in NumPy,
 * which is SIMD-vectorised), with the same float32 and float64 operations in the same order,
 * so its results are those of clip.py bit for bit (tests/detect/test_detect_clip_kernel.py).
 *
 * Built by setup.py as an optional extension: without a C compiler the package uses
 * clip.py's NumPy path. No NumPy headers: arrays arrive through the buffer protocol.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>

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
    for (Py_ssize_t r = 0; r < rows; r++) {
        const float *s = all + r * m;
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
        med_out[r] = med;
        low_out[r] = s[lo < m - 1 ? lo : m - 1];
        high_out[r] = s[hi - 1 > 0 ? hi - 1 : 0];
        kept_out[r] = (int64_t)(hi - lo);
    }
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

static PyMethodDef methods[] = {
    {"clip_sorted", clip_sorted, METH_VARARGS, "Sigma-clip the sorted rows (see clip.py)."},
    {"mad_sorted", mad_sorted, METH_VARARGS, "MAD of the sorted rows' first n values."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_clipc", NULL, -1, methods};

PyMODINIT_FUNC PyInit__clipc(void) { return PyModule_Create(&module); }
