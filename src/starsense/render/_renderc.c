/* Compiled core of frame rendering: adding star stamps, and the detector's read-out.
 *
 * add_stamps  image[flat[k]] += vals[k] for k in order, each sum formed in float64 and stored
 *             as float32: what `image[box] += stamp` does star by star (and np.add.at, 20x
 *             slower on mixed types), equal bit for bit.
 * read_out    expected electrons -> 16-bit counts for a detector with read noise (and optional
 *             uniform dark charge), one pass over the frame (render/readout.py says why each
 *             step keeps the frame's statistics): a standard normal per pixel from 32 random
 *             bits by a 4096-bin inverse-CDF table, linear within a bin, the outermost bins
 *             by the quantile function (Acklam's approximation);
 *             the charge Poisson(lambda) where lambda >= cut (drawn by NumPy, given in
 *             pixel order), else folded into the normal: lambda + sqrt(sigma_r^2 + lambda) z;
 *             then gain, bias, round to nearest, clip to [0, saturation].
 *
 * Built by setup.py as an optional extension: without a C compiler the package renders with
 * render/noise.py alone. No NumPy headers: arrays arrive through the buffer protocol.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>

static int check(Py_buffer *b, Py_ssize_t bytes, const char *what)
{
    if (b->len < bytes) {
        PyErr_Format(PyExc_ValueError, "_renderc: %s holds %zd bytes, needs %zd", what, b->len,
                     bytes);
        return 0;
    }
    return 1;
}

/* add_stamps(image, n_pixels, flat, vals, n): image float32 (n_pixels,), flat int64 (n,),
 * vals float64 (n,). */
static PyObject *add_stamps(PyObject *self, PyObject *args)
{
    Py_buffer ib, fb, vb;
    Py_ssize_t npix, n;
    PyObject *result = NULL;
    if (!PyArg_ParseTuple(args, "w*ny*y*n", &ib, &npix, &fb, &vb, &n))
        return NULL;
    if (!check(&ib, npix * 4, "image") || !check(&fb, n * 8, "flat") ||
        !check(&vb, n * 8, "vals"))
        goto done;
    {
        float *img = ib.buf;
        const int64_t *flat = fb.buf;
        const double *vals = vb.buf;
        for (Py_ssize_t k = 0; k < n; k++) {
            int64_t i = flat[k];
            if (i < 0 || i >= npix) {
                PyErr_SetString(PyExc_IndexError, "_renderc.add_stamps: pixel out of range");
                goto done;
            }
            img[i] = (float)((double)img[i] + vals[k]);
        }
        Py_INCREF(Py_None);
        result = Py_None;
    }
done:
    PyBuffer_Release(&ib);
    PyBuffer_Release(&fb);
    PyBuffer_Release(&vb);
    return result;
}

/* The standard normal quantile at p = (u + 1/2) / 2^32 (Acklam's rational approximation,
 * relative error < 1.15e-9 over (0, 1)); the upper half from the lower by symmetry. */
static double normal_quantile(uint32_t u)
{
    static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,
                               -2.759285104469687e+02, 1.383577518672690e+02,
                               -3.066479806614716e+01, 2.506628277459239e+00};
    static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02,
                               -1.556989798598866e+02, 6.680131188771972e+01,
                               -1.328068155288572e+01};
    static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01,
                               -2.400758277161838e+00, -2.549732539343734e+00,
                               4.374664141464968e+00, 2.938163982698783e+00};
    static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01,
                               2.445134137142996e+00, 3.754408661907416e+00};
    const double scale = 1.0 / 4294967296.0;
    uint32_t upper = u >> 31, v = u ^ (0u - upper); /* the upper half mirrored: ~u */
    double p = ((double)v + 0.5) * scale;
    double x;
    if (p < 0.02425) {
        double q = sqrt(-2.0 * log(p));
        x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
            ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
    } else {
        double q = p - 0.5, r = q * q;
        x = (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
            (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0);
    }
    return upper ? -x : x; /* a conditional move */
}

/* normal_quantiles(u, n, out): out[k] = normal_quantile(u[k]); u uint32 (n,), out float64. */
static PyObject *normal_quantiles(PyObject *self, PyObject *args)
{
    Py_buffer ub, ob;
    Py_ssize_t n;
    PyObject *result = NULL;
    if (!PyArg_ParseTuple(args, "y*nw*", &ub, &n, &ob))
        return NULL;
    if (check(&ub, n * 4, "u") && check(&ob, n * 8, "out")) {
        const uint32_t *u = ub.buf;
        double *out = ob.buf;
        for (Py_ssize_t k = 0; k < n; k++)
            out[k] = normal_quantile(u[k]);
        Py_INCREF(Py_None);
        result = Py_None;
    }
    PyBuffer_Release(&ub);
    PyBuffer_Release(&ob);
    return result;
}

/* A standard normal from 32 random bits u: bin j = u >> 20 of 4096 equally likely ones, a
 * point (f + 1/2) / 2^20 of the way across it (f the low 20 bits) on the line between its
 * edge quantiles (table[2j], table[2j + 1] = edge, width / 2^20; 64 KB, in cache); the two
 * outermost bins (beyond 3.49 sigma) by the quantile function itself. */
static inline double normal_from_bits(uint32_t u, const double *table)
{
    uint32_t j = u >> 20;
    if (j == 0 || j == 4095)
        return normal_quantile(u);
    return table[2 * j] + ((double)(u & 0xfffffu) + 0.5) * table[2 * j + 1];
}

/* normal_draws(u, n, table, out): out[k] = normal_from_bits(u[k]) (the read-out's draws). */
static PyObject *normal_draws(PyObject *self, PyObject *args)
{
    Py_buffer ub, tb, ob;
    Py_ssize_t n;
    PyObject *result = NULL;
    if (!PyArg_ParseTuple(args, "y*ny*w*", &ub, &n, &tb, &ob))
        return NULL;
    if (check(&ub, n * 4, "u") && check(&tb, 4096 * 16, "table") && check(&ob, n * 8, "out")) {
        const uint32_t *u = ub.buf;
        double *out = ob.buf;
        for (Py_ssize_t k = 0; k < n; k++)
            out[k] = normal_from_bits(u[k], tb.buf);
        Py_INCREF(Py_None);
        result = Py_None;
    }
    PyBuffer_Release(&ub);
    PyBuffer_Release(&tb);
    PyBuffer_Release(&ob);
    return result;
}

/* read_out(expected, n, raw, table, pois, pidx, npois, dark, sigma_r, gain, bias, saturation,
 *          full_well, out)
 * expected float32 (n,); raw uint64 ((n + 1) / 2,): pixel 2k takes the low 32 bits of raw[k],
 * pixel 2k + 1 the high; table float64 (4096, 2); pois, pidx int64 (npois,), pidx ascending;
 * out uint16 (n,). */
static PyObject *read_out(PyObject *self, PyObject *args)
{
    Py_buffer eb, rb, tab, pb, ixb, ob;
    Py_ssize_t n, npois;
    double dark, sigma_r, gain, bias, sat, fw;
    PyObject *result = NULL;
    if (!PyArg_ParseTuple(args, "y*ny*y*y*y*nddddddw*", &eb, &n, &rb, &tab, &pb, &ixb, &npois,
                          &dark, &sigma_r, &gain, &bias, &sat, &fw, &ob))
        return NULL;
    if (!check(&eb, n * 4, "expected") || !check(&rb, ((n + 1) / 2) * 8, "raw") ||
        !check(&tab, 4096 * 16, "table") ||
        !check(&pb, npois * 8, "pois") || !check(&ixb, npois * 8, "pidx") ||
        !check(&ob, n * 2, "out"))
        goto done;
    {
        const float *e = eb.buf;
        const uint64_t *raw = rb.buf;
        const double *table = tab.buf;
        const int64_t *pois = pb.buf, *pidx = ixb.buf;
        uint16_t *out = ob.buf;
        Py_ssize_t next = 0;
        double var_r = sigma_r * sigma_r;
        for (Py_ssize_t i = 0; i < n; i++) {
            uint64_t r = raw[i >> 1];
            double z = normal_from_bits((i & 1) ? (uint32_t)(r >> 32) : (uint32_t)r, table);
            double el;
            if (next < npois && pidx[next] == i) {
                double p = (double)pois[next++];
                el = (p < fw ? p : fw) + sigma_r * z;
            } else {
                double lam = (double)e[i] + dark;
                el = lam == 0.0 ? sigma_r * z : lam + sqrt(var_r + lam) * z;
            }
            /* round to the nearest count (a tie, of probability 0 here, rounds up) and clip to
             * [0, sat]: truncation of the clamped value + 1/2 (min / max: no branch) */
            double cnt = fmin(fmax(gain * el + bias + 0.5, 0.0), sat + 0.5);
            out[i] = (uint16_t)(int64_t)cnt;
        }
        Py_INCREF(Py_None);
        result = Py_None;
    }
done:
    PyBuffer_Release(&eb);
    PyBuffer_Release(&rb);
    PyBuffer_Release(&tab);
    PyBuffer_Release(&pb);
    PyBuffer_Release(&ixb);
    PyBuffer_Release(&ob);
    return result;
}

static PyMethodDef methods[] = {
    {"add_stamps", add_stamps, METH_VARARGS, "Add float64 values to float32 pixels in order."},
    {"read_out", read_out, METH_VARARGS, "Expected electrons to noisy 16-bit counts."},
    {"normal_quantiles", normal_quantiles, METH_VARARGS, "Normal quantiles of 32-bit integers."},
    {"normal_draws", normal_draws, METH_VARARGS, "The read-out's normal draws."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_renderc", NULL, -1, methods};

PyMODINIT_FUNC PyInit__renderc(void) { return PyModule_Create(&module); }
