/* Compiled kernel of the row and column pattern (pattern.py's _offsets): for each line of a
 * float32 frame, the sum (float64) and the count of its pixels below a cut, in one pass.
 *
 *   line_sums(sub, rows, cols, noise, map, factor, axis, total, count)
 *       sub    float32 (rows, cols), the background-subtracted frame;
 *       noise  float32: the noise map (rows, cols) when map is 1, else one value;
 *       factor float32: a pixel is kept when sub < factor * noise (float32 product, as NumPy's
 *              np.float32(factor) * noise);
 *       axis   1: one sum per row (total, count of rows entries); 0: one per column;
 *       total  float64 out, count int64 out.
 *
 * The comparisons are NumPy's (float32); the sums run in order along each line, so they
 * differ from NumPy's pairwise float64 sums by the rounding of float64 sums (~1e-16 relative).
 * Built by setup.py as an optional extension; pattern.py's NumPy form is the reference.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

static void sums(const float *sub, Py_ssize_t rows, Py_ssize_t cols, const float *noise,
                 int map, float factor, int axis, double *total, int64_t *count)
{
    Py_ssize_t lines = axis == 1 ? rows : cols;
    memset(total, 0, lines * sizeof(double));
    memset(count, 0, lines * sizeof(int64_t));
    float cut = factor * noise[0];
    for (Py_ssize_t r = 0; r < rows; r++) {
        const float *row = sub + r * cols;
        const float *nrow = map ? noise + r * cols : NULL;
        if (axis == 1) {
            double t = 0.0;
            int64_t n = 0;
            for (Py_ssize_t c = 0; c < cols; c++) {
                float v = row[c];
                if (v < (map ? factor * nrow[c] : cut)) {
                    t += (double)v;
                    n++;
                }
            }
            total[r] = t;
            count[r] = n;
        } else {
            for (Py_ssize_t c = 0; c < cols; c++) {
                float v = row[c];
                if (v < (map ? factor * nrow[c] : cut)) {
                    total[c] += (double)v;
                    count[c]++;
                }
            }
        }
    }
}

static PyObject *line_sums(PyObject *self, PyObject *args)
{
    Py_buffer sb, nb, tb, cb;
    Py_ssize_t rows, cols;
    int map, axis;
    float factor;
    if (!PyArg_ParseTuple(args, "y*nny*ifiw*w*", &sb, &rows, &cols, &nb, &map, &factor, &axis,
                          &tb, &cb))
        return NULL;
    PyObject *result = NULL;
    Py_ssize_t pixels = rows * cols, lines = axis == 1 ? rows : cols;
    if (rows < 0 || cols < 0 || (axis != 0 && axis != 1) || sb.len < pixels * 4
        || nb.len < (map ? pixels : 1) * 4 || tb.len < lines * 8 || cb.len < lines * 8) {
        PyErr_SetString(PyExc_ValueError, "line_sums: bad shape, axis or buffer size");
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    sums((const float *)sb.buf, rows, cols, (const float *)nb.buf, map, factor, axis,
         (double *)tb.buf, (int64_t *)cb.buf);
    Py_END_ALLOW_THREADS
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&sb);
    PyBuffer_Release(&nb);
    PyBuffer_Release(&tb);
    PyBuffer_Release(&cb);
    return result;
}

static PyMethodDef methods[] = {
    {"line_sums", line_sums, METH_VARARGS, "Sums and counts of each line's pixels below a cut."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_linesc", NULL, -1, methods};

PyMODINIT_FUNC PyInit__linesc(void) { return PyModule_Create(&module); }
