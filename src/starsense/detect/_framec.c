/* Compiled kernels of whole-frame detection: the PSF correlation, the median of the filtered
 * noise, the labelling of lit pixels.
 *
 * Each is the algorithm of its NumPy form, with the same float32 operations in the same order
 * (built without fused multiply-adds), so its results are those of the NumPy form bit for bit
 * (tests/detect/test_detect_frame_kernel.py):
 *
 *   correlate   matched.py's gaussian_correlate: a separable correlation with a symmetric
 *               float32 kernel, edge pixels repeated, along the rows then down the columns,
 *               the taps in symmetric pairs ((p[-j] + p[+j]) * t[j], added in order of j);
 *   median      np.median of a float32 vector (matched.py's _median_in_place): the k-th
 *               smallest value by a radix selection on the float's bits (three passes of an
 *               11-bit histogram), no reordering; for an even count the mean of the two
 *               middle values in float32;
 *   label       regions.py's label_pixels: the connected regions (4- or 8-connected) of a
 *               sparse, ascending list of lit pixels, numbered 1..n in the order of their first
 *               pixel (scipy.ndimage.label's numbering), by union-find over each pixel's
 *               neighbours to the left and in the row above;
 *   subtract    background.py's subtract_level: np.subtract(a, level, dtype=float32) and the
 *               flat indices of the result above a threshold (np.flatnonzero(sub > t)), one
 *               pass over the frame, block by block (``above``: the indices alone);
 *   hot         background.py's hot_pixel_mask past its first cut: of the candidate pixels
 *               (above the threshold at the frame's lowest noise, with their own noise), those
 *               above the threshold at their noise whose 8 neighbours stay below the allowed
 *               level, or which with their brightest 4-neighbour form a pair whose 10
 *               surrounding pixels do (the same float32 comparisons);
 *   line_sums   pattern.py's line_offsets: for each row (or column) of a float32 frame, the
 *               float64 sum and the count of its pixels below factor x noise (a map or one
 *               value; NumPy's float32 comparisons), in one pass; the sums run in order along
 *               each line, so they differ from NumPy's pairwise sums by float64 rounding.
 *
 * Built by setup.py as an optional extension: without a C compiler the package runs the NumPy
 * forms. No NumPy headers: arrays arrive through the buffer protocol.
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

/* ---------------------------------------------------------------------------------------- */
/* correlate(a, rows, cols, taps, radius, out): a, out float32 (rows, cols), taps (radius+1) */

/* One row along the rows: padded by r repeated edge pixels (``padded``, cols + 2r floats),
 * then the taps one after another over the whole row (a loop the compiler vectorises). */
static inline void correlate_row(const float *row, Py_ssize_t cols, const float *t, int r, float *acc,
                          float *padded)
{
    for (int j = 0; j < r; j++) {
        padded[j] = row[0];
        padded[r + cols + j] = row[cols - 1];
    }
    memcpy(padded + r, row, cols * sizeof(float));
    const float *p = padded + r;
    const float t0 = t[0];
    for (Py_ssize_t c = 0; c < cols; c++)
        acc[c] = p[c] * t0;
    for (int j = 1; j <= r; j++) {
        const float tj = t[j];
        const float *left = p - j, *right = p + j;
        for (Py_ssize_t c = 0; c < cols; c++) {
            float pair = left[c] + right[c];
            pair = pair * tj;
            acc[c] = acc[c] + pair;
        }
    }
}

static Py_ssize_t clamp_row(Py_ssize_t i, Py_ssize_t rows)
{
    return i < 0 ? 0 : (i >= rows ? rows - 1 : i);
}

/* The rows pass into a ring of 2r + 1 rows (``ring``, in the cache), each output row taken
 * down the columns from the ring as soon as its rows are there: the frame is read once and
 * written once. Row i of the rows pass sits in slot i % (2r + 1). */
#if defined(__GNUC__) && defined(__x86_64__) && defined(__linux__)
/* AVX2 where the processor has it (chosen at load time), SSE2 otherwise: the same float32
 * operations element by element (no fused multiply-add: -ffp-contract=off), wider vectors */
__attribute__((target_clones("avx2", "default")))
#endif
static void correlate_frame(const float *a, Py_ssize_t rows, Py_ssize_t cols, const float *t,
                            int r, float *ring, float *padded, float *out)
{
    Py_ssize_t slots = 2 * (Py_ssize_t)r + 1, done = 0; /* rows of the rows pass so far */
    for (Py_ssize_t i = 0; i < rows; i++) {
        Py_ssize_t need = clamp_row(i + r, rows);
        for (; done <= need; done++)
            correlate_row(a + done * cols, cols, t, r, ring + (done % slots) * cols, padded);
        float *o = out + i * cols;
        const float *mid = ring + (i % slots) * cols;
        for (Py_ssize_t c = 0; c < cols; c++)
            o[c] = mid[c] * t[0];
        for (int j = 1; j <= r; j++) {
            const float *u = ring + (clamp_row(i - j, rows) % slots) * cols;
            const float *d = ring + (clamp_row(i + j, rows) % slots) * cols;
            const float tj = t[j];
            for (Py_ssize_t c = 0; c < cols; c++) {
                float pair = u[c] + d[c];
                pair = pair * tj;
                o[c] = o[c] + pair;
            }
        }
    }
}

static PyObject *correlate(PyObject *self, PyObject *args)
{
    Py_buffer ab, tb, ob;
    Py_ssize_t rows, cols;
    int radius;
    if (!PyArg_ParseTuple(args, "y*nny*iw*", &ab, &rows, &cols, &tb, &radius, &ob))
        return NULL;
    PyObject *result = NULL;
    Py_ssize_t bytes = rows * cols * 4;
    if (rows < 1 || cols < 1 || radius < 0 || check(&ab, bytes, "a")
        || check(&tb, (Py_ssize_t)(radius + 1) * 4, "taps") || check(&ob, bytes, "out")) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "bad shape");
        goto done;
    }
    float *ring = malloc((2 * (Py_ssize_t)radius + 1) * cols * sizeof(float));
    float *padded = malloc((cols + 2 * (Py_ssize_t)radius) * sizeof(float));
    if (ring == NULL || padded == NULL) {
        free(ring);
        free(padded);
        PyErr_NoMemory();
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    correlate_frame((const float *)ab.buf, rows, cols, (const float *)tb.buf, radius, ring,
                    padded, (float *)ob.buf);
    Py_END_ALLOW_THREADS
    free(ring);
    free(padded);
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&ab);
    PyBuffer_Release(&tb);
    PyBuffer_Release(&ob);
    return result;
}

/* ---------------------------------------------------------------------------------------- */
/* median(z, n, keys): np.median of a 1-D float32 vector (no NaN), as a float; keys: n uint32 */

/* The float's bits as an unsigned key of the same order (-0.0 sorts just below +0.0, which
 * compare equal as floats: either is "the" k-th value, and they are equal). */
static inline uint32_t key_of(float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    /* negative: all bits flipped; positive: the sign bit set (no branch: signs are random) */
    return u ^ ((uint32_t)((int32_t)u >> 31) | 0x80000000u);
}

static inline float float_of(uint32_t k)
{
    uint32_t u = (k & 0x80000000u) ? (k & 0x7fffffffu) : ~k;
    float f;
    memcpy(&f, &u, 4);
    return f;
}

/* The key of the k-th smallest (0-based) of the n floats z, 0 <= k < n, by a radix
 * selection: a histogram of the keys' top 11 bits finds the bin that holds it, the keys in
 * that bin are kept (in ``keys``, compacted without branches), then the next 11 and the last
 * 10 bits likewise (2,048 counters, in the L1 cache; four copies filled in turn, so that runs
 * of equal bins do not wait on each other). The first level reads the floats themselves, so
 * the whole vector is read twice. *next is the key of the (k + 1)-th smallest (k + 1 < n): the
 * same key when more than k + 1 keys are at most it, else the least key above it, tracked
 * among the keys of the bins above the chosen one at each level. */
static uint32_t select_key(const float *z, Py_ssize_t n, Py_ssize_t k, uint32_t *keys,
                           uint32_t *next)
{
    static const int shift[3] = {21, 10, 0}, width[3] = {11, 11, 10};
    uint32_t hist[4][2048];
    uint32_t prefix = 0, above = UINT32_MAX;
    Py_ssize_t below = 0, m = n;
    for (int level = 0; level < 3; level++) {
        uint32_t mask = (1u << width[level]) - 1, sh = (uint32_t)shift[level];
        memset(hist, 0, sizeof(hist));
        Py_ssize_t i = 0;
        if (level == 0) {
            for (; i + 4 <= m; i += 4) {
                hist[0][key_of(z[i]) >> sh]++;
                hist[1][key_of(z[i + 1]) >> sh]++;
                hist[2][key_of(z[i + 2]) >> sh]++;
                hist[3][key_of(z[i + 3]) >> sh]++;
            }
            for (; i < m; i++)
                hist[0][key_of(z[i]) >> sh]++;
        } else {
            for (; i + 4 <= m; i += 4) {
                hist[0][(keys[i] >> sh) & mask]++;
                hist[1][(keys[i + 1] >> sh) & mask]++;
                hist[2][(keys[i + 2] >> sh) & mask]++;
                hist[3][(keys[i + 3] >> sh) & mask]++;
            }
            for (; i < m; i++)
                hist[0][(keys[i] >> sh) & mask]++;
        }
        uint32_t b = 0;
        Py_ssize_t here = 0;
        for (; b <= mask; b++) {
            here = (Py_ssize_t)hist[0][b] + hist[1][b] + hist[2][b] + hist[3][b];
            if (below + here > k)
                break;
            below += here;
        }
        prefix |= b << sh;
        Py_ssize_t kept = 0; /* keep the keys of bin b; below still counts every key under it */
        for (i = 0; i < m; i++) {
            uint32_t key = level == 0 ? key_of(z[i]) : keys[i];
            uint32_t bin = (key >> sh) & mask;
            above = (bin > b && key < above) ? key : above;
            if (level < 2) {
                keys[kept] = key;
                kept += bin == b;
            }
        }
        if (level == 2) {
            *next = below + here > k + 1 ? prefix : above;
            break;
        }
        m = kept;
    }
    return prefix;
}

/* The two middle values of the n floats z (n >= 1; equal for odd n). keys: n scratch keys. */
static void middle_pair(const float *z, Py_ssize_t n, uint32_t *keys, float *lower, float *upper)
{
    Py_ssize_t k = (n - 1) / 2;
    uint32_t next, key = select_key(z, n, k, keys, &next);
    *lower = float_of(key);
    *upper = n % 2 == 0 ? float_of(next) : *lower;
}

static PyObject *median(PyObject *self, PyObject *args)
{
    Py_buffer zb, kb;
    Py_ssize_t n;
    if (!PyArg_ParseTuple(args, "y*nw*", &zb, &n, &kb))
        return NULL;
    PyObject *result = NULL;
    if (n < 1 || check(&zb, n * 4, "z") || check(&kb, n * 4, "keys")) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "median of nothing");
        goto done;
    }
    const float *z = (const float *)zb.buf;
    float m, upper;
    Py_BEGIN_ALLOW_THREADS
    middle_pair(z, n, (uint32_t *)kb.buf, &m, &upper);
    if (n % 2 == 0) {
        float s = m + upper;
        m = s / 2.0f;
    }
    Py_END_ALLOW_THREADS
    result = PyFloat_FromDouble((double)m);
done:
    PyBuffer_Release(&zb);
    PyBuffer_Release(&kb);
    return result;
}

/* ---------------------------------------------------------------------------------------- */
/* label(idx, p, cols, connectivity, labels) -> n: idx int64 ascending, labels int32 (p,)    */

static Py_ssize_t find(Py_ssize_t *parent, Py_ssize_t i)
{
    while (parent[i] != i) {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    return i;
}

static void unite(Py_ssize_t *parent, Py_ssize_t a, Py_ssize_t b)
{
    a = find(parent, a);
    b = find(parent, b);
    if (a == b)
        return;
    if (a < b) /* the root is the component's first pixel */
        parent[b] = a;
    else
        parent[a] = b;
}

static void label_sorted(const int64_t *idx, Py_ssize_t p, int64_t cols, int eight,
                         Py_ssize_t *parent, int32_t *labels, Py_ssize_t *n_out)
{
    Py_ssize_t up = 0; /* first pixel that may be in the row above, at or right of c - 1 */
    for (Py_ssize_t i = 0; i < p; i++) {
        parent[i] = i;
        int64_t v = idx[i], c = v % cols;
        if (i > 0 && idx[i - 1] == v - 1 && c > 0)
            unite(parent, i, i - 1);
        int64_t first = v - cols - (eight && c > 0 ? 1 : 0);
        int64_t last = v - cols + (eight && c + 1 < cols ? 1 : 0);
        while (up < i && idx[up] < first)
            up++;
        for (Py_ssize_t j = up; j < i && idx[j] <= last; j++)
            unite(parent, i, j);
    }
    Py_ssize_t n = 0;
    for (Py_ssize_t i = 0; i < p; i++) {
        Py_ssize_t root = find(parent, i);
        if (root == i)
            labels[i] = (int32_t)++n;
        else
            labels[i] = labels[root]; /* root < i: labelled already */
    }
    *n_out = n;
}

static PyObject *label(PyObject *self, PyObject *args)
{
    Py_buffer ib, lb;
    Py_ssize_t p, cols;
    int connectivity;
    if (!PyArg_ParseTuple(args, "y*nniw*", &ib, &p, &cols, &connectivity, &lb))
        return NULL;
    PyObject *result = NULL;
    if (p < 0 || cols < 1 || check(&ib, p * 8, "idx") || check(&lb, p * 4, "labels")) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "bad shape");
        goto done;
    }
    Py_ssize_t *parent = malloc((p > 0 ? p : 1) * sizeof(Py_ssize_t));
    if (parent == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    Py_ssize_t n = 0;
    Py_BEGIN_ALLOW_THREADS
    label_sorted((const int64_t *)ib.buf, p, (int64_t)cols, connectivity == 8, parent,
                 (int32_t *)lb.buf, &n);
    Py_END_ALLOW_THREADS
    free(parent);
    result = PyLong_FromSsize_t(n);
done:
    PyBuffer_Release(&ib);
    PyBuffer_Release(&lb);
    return result;
}

/* ---------------------------------------------------------------------------------------- */
/* hot(sub, rows, cols, flat, noise, p, threshold_sigma, hot): sub float32 (rows, cols), flat */
/* int64 (p,), noise float32 (p,) (at least 1e-12), hot uint8 (rows, cols), set where hot    */

/* The largest of sub at (r + dr[k], c + dc[k]), k < n, inside the frame; -inf if none. */
static float ring_max(const float *sub, Py_ssize_t rows, Py_ssize_t cols, Py_ssize_t r,
                      Py_ssize_t c, const int *dr, const int *dc, int n)
{
    float out = -INFINITY;
    for (int k = 0; k < n; k++) {
        Py_ssize_t rr = r + dr[k], cc = c + dc[k];
        if (rr < 0 || rr >= rows || cc < 0 || cc >= cols)
            continue;
        float v = sub[rr * cols + cc];
        if (v > out)
            out = v;
    }
    return out;
}

static const int EIGHT_DR[8] = {-1, -1, -1, 0, 0, 1, 1, 1};
static const int EIGHT_DC[8] = {-1, 0, 1, -1, 1, -1, 0, 1};
/* the 4-neighbours in background.py's order: up, down, left, right */
static const int SIDE_DR[4] = {-1, 1, 0, 0};
static const int SIDE_DC[4] = {0, 0, -1, 1};

/* The 10 pixels around the pair (0, 0) + (dr, dc): the box around the two less the two. */
static int pair_ring(int dr, int dc, int *rr, int *cc)
{
    int n = 0;
    int r_lo = (dr < 0 ? dr : 0) - 1, r_hi = (dr > 0 ? dr : 0) + 1;
    int c_lo = (dc < 0 ? dc : 0) - 1, c_hi = (dc > 0 ? dc : 0) + 1;
    for (int i = r_lo; i <= r_hi; i++)
        for (int j = c_lo; j <= c_hi; j++) {
            if ((i == 0 && j == 0) || (i == dr && j == dc))
                continue;
            rr[n] = i;
            cc[n] = j;
            n++;
        }
    return n;
}

static Py_ssize_t clamp(Py_ssize_t v, Py_ssize_t n) { return v < 0 ? 0 : (v >= n ? n - 1 : v); }

static void hot_pixels(const float *sub, Py_ssize_t rows, Py_ssize_t cols, const int64_t *flat,
                       const float *noise, Py_ssize_t p, float ts, uint8_t *hot)
{
    int ring_r[4][10], ring_c[4][10], ring_n[4];
    for (int s = 0; s < 4; s++)
        ring_n[s] = pair_ring(SIDE_DR[s], SIDE_DC[s], ring_r[s], ring_c[s]);
    for (Py_ssize_t i = 0; i < p; i++) {
        Py_ssize_t r = (Py_ssize_t)(flat[i] / cols), c = (Py_ssize_t)(flat[i] % cols);
        float v = sub[r * cols + c], n = noise[i];
        if (!(v > ts * n))
            continue;
        float three = 3.0f * n, part = 0.15f * v;
        float allowed = three >= part ? three : part;
        if (ring_max(sub, rows, cols, r, c, EIGHT_DR, EIGHT_DC, 8) < allowed) {
            hot[r * cols + c] = 1;
            continue;
        }
        int best = 0; /* the brightest 4-neighbour, the first of equals */
        float top = -INFINITY;
        for (int s = 0; s < 4; s++) {
            float side = ring_max(sub, rows, cols, r, c, SIDE_DR + s, SIDE_DC + s, 1);
            if (s == 0 || side > top) {
                top = side;
                best = s;
            }
        }
        Py_ssize_t r2 = clamp(r + SIDE_DR[best], rows), c2 = clamp(c + SIDE_DC[best], cols);
        if (ring_max(sub, rows, cols, r, c, ring_r[best], ring_c[best], ring_n[best]) < allowed
            && v >= sub[r2 * cols + c2]) {
            hot[r * cols + c] = 1;
            hot[r2 * cols + c2] = 1;
        }
    }
}

static PyObject *hot(PyObject *self, PyObject *args)
{
    Py_buffer sb, fb, nb, hb;
    Py_ssize_t rows, cols, p;
    float ts;
    if (!PyArg_ParseTuple(args, "y*nny*y*nfw*", &sb, &rows, &cols, &fb, &nb, &p, &ts, &hb))
        return NULL;
    PyObject *result = NULL;
    if (rows < 1 || cols < 1 || p < 0 || check(&sb, rows * cols * 4, "sub")
        || check(&fb, p * 8, "flat") || check(&nb, p * 4, "noise")
        || check(&hb, rows * cols, "hot")) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "bad shape");
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    hot_pixels((const float *)sb.buf, rows, cols, (const int64_t *)fb.buf,
               (const float *)nb.buf, p, ts, (uint8_t *)hb.buf);
    Py_END_ALLOW_THREADS
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&sb);
    PyBuffer_Release(&fb);
    PyBuffer_Release(&nb);
    PyBuffer_Release(&hb);
    return result;
}

/* ---------------------------------------------------------------------------------------- */
/* subtract(a, kind, level, n, out, thr, idx, cap) -> count: out = float32(a) - level (as     */
/* np.subtract(a, level, dtype=float32)); idx (int64, cap) the flat indices where out > thr.  */
/* above(x, n, thr, idx, cap) -> count: the same indices of a float32 vector (np.flatnonzero  */
/* of x > thr). The count is the number above (more than cap: only the first cap written).    */

#define BLOCK 512

/* The indices of x[0:m] above thr, offset by base, appended to idx (at most cap in all). */
static inline Py_ssize_t collect(const float *x, Py_ssize_t m, float thr, Py_ssize_t base,
                                 int64_t *idx, Py_ssize_t cap, Py_ssize_t count)
{
    int any = 0;
    for (Py_ssize_t j = 0; j < m; j++) /* vectorised: a block is mostly below */
        any |= x[j] > thr;
    if (!any)
        return count;
    for (Py_ssize_t j = 0; j < m; j++)
        if (x[j] > thr) {
            if (count < cap)
                idx[count] = base + j;
            count++;
        }
    return count;
}

#define SUBTRACT_BLOCKS(T)                                                                     \
    for (Py_ssize_t b0 = 0; b0 < n; b0 += BLOCK) {                                             \
        Py_ssize_t m = n - b0 < BLOCK ? n - b0 : BLOCK;                                        \
        const T *src = (const T *)a + b0;                                                      \
        const float *lev = level + b0;                                                         \
        float *o = out + b0;                                                                   \
        for (Py_ssize_t j = 0; j < m; j++)                                                     \
            o[j] = (float)src[j] - lev[j];                                                     \
        count = collect(o, m, thr, b0, idx, cap, count);                                       \
    }

static Py_ssize_t subtract_frame(const void *a, char kind, const float *level, Py_ssize_t n,
                                 float *out, float thr, int64_t *idx, Py_ssize_t cap)
{
    Py_ssize_t count = 0;
    switch (kind) {
    case 'B':
        SUBTRACT_BLOCKS(uint8_t)
        break;
    case 'H':
        SUBTRACT_BLOCKS(uint16_t)
        break;
    case 'h':
        SUBTRACT_BLOCKS(int16_t)
        break;
    case 'f':
        SUBTRACT_BLOCKS(float)
        break;
    default: /* 'd': float64 cast to float32 first, as dtype=float32 does */
        for (Py_ssize_t b0 = 0; b0 < n; b0 += BLOCK) {
            Py_ssize_t m = n - b0 < BLOCK ? n - b0 : BLOCK;
            const double *src = (const double *)a + b0;
            for (Py_ssize_t j = 0; j < m; j++)
                out[b0 + j] = (float)src[j] - level[b0 + j];
            count = collect(out + b0, m, thr, b0, idx, cap, count);
        }
    }
    return count;
}

static PyObject *subtract(PyObject *self, PyObject *args)
{
    Py_buffer ab, lb, ob, ib;
    int kind;
    Py_ssize_t n, cap;
    float thr;
    if (!PyArg_ParseTuple(args, "y*Cy*nw*fw*n", &ab, &kind, &lb, &n, &ob, &thr, &ib, &cap))
        return NULL;
    PyObject *result = NULL;
    Py_ssize_t item = kind == 'B' ? 1 : (kind == 'H' || kind == 'h') ? 2 : kind == 'f' ? 4 : 8;
    if (kind != 'B' && kind != 'H' && kind != 'h' && kind != 'f' && kind != 'd') {
        PyErr_Format(PyExc_ValueError, "kind %c is not one of B, H, h, f, d", kind);
        goto done;
    }
    if (n < 0 || cap < 0 || check(&ab, n * item, "a") || check(&lb, n * 4, "level")
        || check(&ob, n * 4, "out") || check(&ib, cap * 8, "idx")) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "bad shape");
        goto done;
    }
    Py_ssize_t count;
    Py_BEGIN_ALLOW_THREADS
    count = subtract_frame(ab.buf, (char)kind, (const float *)lb.buf, n, (float *)ob.buf, thr,
                           (int64_t *)ib.buf, cap);
    Py_END_ALLOW_THREADS
    result = PyLong_FromSsize_t(count);
done:
    PyBuffer_Release(&ab);
    PyBuffer_Release(&lb);
    PyBuffer_Release(&ob);
    PyBuffer_Release(&ib);
    return result;
}

static PyObject *above(PyObject *self, PyObject *args)
{
    Py_buffer xb, ib;
    Py_ssize_t n, cap;
    float thr;
    if (!PyArg_ParseTuple(args, "y*nfw*n", &xb, &n, &thr, &ib, &cap))
        return NULL;
    PyObject *result = NULL;
    if (n < 0 || cap < 0 || check(&xb, n * 4, "x") || check(&ib, cap * 8, "idx")) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "bad shape");
        goto done;
    }
    Py_ssize_t count = 0;
    const float *x = (const float *)xb.buf;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t b0 = 0; b0 < n; b0 += BLOCK)
        count = collect(x + b0, n - b0 < BLOCK ? n - b0 : BLOCK, thr, b0, (int64_t *)ib.buf, cap,
                        count);
    Py_END_ALLOW_THREADS
    result = PyLong_FromSsize_t(count);
done:
    PyBuffer_Release(&xb);
    PyBuffer_Release(&ib);
    return result;
}

/* ---------------------------------------------------------------------------------------- */
/* line_sums(sub, rows, cols, noise, map, factor, axis, total, count) */

static void line_sums_kernel(const float *sub, Py_ssize_t rows, Py_ssize_t cols, const float *noise,
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
    line_sums_kernel((const float *)sb.buf, rows, cols, (const float *)nb.buf, map, factor, axis,
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
    {"correlate", correlate, METH_VARARGS, "Separable symmetric correlation (matched.py)."},
    {"median", median, METH_VARARGS, "np.median of a float32 vector."},
    {"label", label, METH_VARARGS, "Connected regions of sorted lit pixels (regions.py)."},
    {"hot", hot, METH_VARARGS, "Hot pixels and pairs among candidates (background.py)."},
    {"subtract", subtract, METH_VARARGS, "Frame minus level map, and the pixels above (float32)."},
    {"above", above, METH_VARARGS, "Flat indices of a float32 vector's values above a threshold."},
    {"line_sums", line_sums, METH_VARARGS, "Sums and counts of each line's pixels below a cut."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_framec", NULL, -1, methods};

PyMODINIT_FUNC PyInit__framec(void) { return PyModule_Create(&module); }
