/* Compiled core of tracking: window detection.
 *
 * starsense.detect.windows detects the stars of a tracked frame in small windows around their
 * predicted positions. Its NumPy form (windows.py, streak.py) does the work of a few dozen
 * windows in a few hundred array operations whose cost is NumPy's per-call overhead, not the
 * arithmetic. This kernel (detect_windows) runs the same algorithm window by window and
 * region by region: cut each window from the frame, subtract its level and threshold it
 * (float32, as windows.py), label its lit pixels (8- or 4-connected, never across windows,
 * labels in raster order of their first pixel as scipy.ndimage.label), sum each region
 * (pixels, counts, box, peak), keep the regions the detection logic accepts and no window edge
 * cuts, centroid each (CoG over its box plus a margin, or over the capsule of its predicted
 * streak, iterated as streak.streak_centroids) and drop streaks that run off the frame.
 *
 * Every comparison and every sum over a region's lit pixels is the NumPy form's float32 or
 * float64 operation in the same order; the centroid sums (over a box or a capsule) are exact
 * for whole-number counts, as a camera's are, so the results equal the NumPy form's bit for bit
 * there; otherwise they differ by rounding (tests/detect/test_windows_kernel.py). Built with
 * -ffp-contract=off: no fused multiply-add may change a rounding.
 *
 * Built by setup.py as an optional extension: without a C compiler the package uses the NumPy
 * form. No NumPy headers: arrays arrive through the buffer protocol.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* Columns of one output row of detect_windows. */
enum { X, Y, COUNTS, PIXELS, PEAK, BOX_R0, BOX_R1, BOX_C0, BOX_C1, SXX, SXY, SYX, SYY, NCOL };

typedef struct {
    const char *data;
    char fmt;
    Py_ssize_t cols;
} Frame;

/* The frame's pixel (row, col) as float32 (the NumPy form's astype(float32)). */
static inline float pixel(const Frame *f, Py_ssize_t r, Py_ssize_t c)
{
    Py_ssize_t i = r * f->cols + c;
    switch (f->fmt) {
    case 'B': return (float)((const uint8_t *)f->data)[i];
    case 'b': return (float)((const int8_t *)f->data)[i];
    case 'H': return (float)((const uint16_t *)f->data)[i];
    case 'h': return (float)((const int16_t *)f->data)[i];
    case 'I': return (float)((const uint32_t *)f->data)[i];
    case 'i': return (float)((const int32_t *)f->data)[i];
    case 'L': case 'Q': return (float)((const uint64_t *)f->data)[i];
    case 'l': case 'q': return (float)((const int64_t *)f->data)[i];
    case 'f': return ((const float *)f->data)[i];
    default: return (float)((const double *)f->data)[i];
    }
}

static Py_ssize_t item_size(char fmt)
{
    switch (fmt) {
    case 'B': case 'b': return 1;
    case 'H': case 'h': return 2;
    case 'I': case 'i': case 'f': return 4;
    case 'L': case 'Q': case 'l': case 'q': case 'd': return 8;
    default: return 0;
    }
}

/* Union-find over provisional labels (parent[i] <= i: the root is the smallest). */
static int32_t find(int32_t *parent, int32_t a)
{
    while (parent[a] != a) {
        parent[a] = parent[parent[a]];
        a = parent[a];
    }
    return a;
}

static void join(int32_t *parent, int32_t a, int32_t b)
{
    a = find(parent, a);
    b = find(parent, b);
    if (a < b)
        parent[b] = a;
    else if (b < a)
        parent[a] = b;
}

/* Scratch kept between calls (the GIL serialises them): one window's counts less the level
 * (g_sub, plane(); sized as the others, its pages touched only as far as one window); per
 * pixel of the windows whether lit, and the label; the flat indices of the lit pixels; the
 * union-find parents and final labels of the provisional labels. */
static float *g_sub;
static unsigned char *g_lit;
static int32_t *g_lab, *g_idx, *g_parent, *g_final;
static Py_ssize_t g_npix;

static int reserve(Py_ssize_t npix)
{
    if (npix <= g_npix)
        return 1;
    free(g_sub);
    free(g_lit);
    free(g_lab);
    free(g_idx);
    free(g_parent);
    free(g_final);
    g_sub = malloc(npix * sizeof(float));
    g_lit = malloc(npix);
    g_lab = malloc(npix * sizeof(int32_t));
    g_idx = malloc(npix * sizeof(int32_t));
    g_parent = malloc((npix + 1) * sizeof(int32_t));
    g_final = malloc((npix + 1) * sizeof(int32_t));
    if (!g_sub || !g_lit || !g_lab || !g_idx || !g_parent || !g_final) {
        g_npix = 0;
        return 0;
    }
    g_npix = npix;
    return 1;
}

/* Label the lit pixels idx[0..nlit) (flat, ascending) of the windows (K, h, w): labels in
 * lab at those pixels, 1..n in raster order of each region's first pixel; never across
 * windows. Returns n. */
static Py_ssize_t label_windows(const unsigned char *lit, int32_t *lab, const int32_t *idx,
                                Py_ssize_t nlit, Py_ssize_t h, Py_ssize_t w, int eight)
{
    int32_t *parent = g_parent, *final = g_final, next = 1;
    for (Py_ssize_t q = 0; q < nlit; q++) {
        Py_ssize_t at = idx[q], rest = at % (h * w), i = rest / w, j = rest % w;
        int32_t nb[4];
        int nn = 0;
        if (j > 0 && lit[at - 1])
            nb[nn++] = lab[at - 1];
        if (i > 0) {
            if (lit[at - w])
                nb[nn++] = lab[at - w];
            if (eight && j > 0 && lit[at - w - 1])
                nb[nn++] = lab[at - w - 1];
            if (eight && j + 1 < w && lit[at - w + 1])
                nb[nn++] = lab[at - w + 1];
        }
        if (nn == 0) {
            parent[next] = next;
            lab[at] = next++;
        } else {
            lab[at] = nb[0];
            for (int e = 1; e < nn; e++)
                join(parent, nb[0], nb[e]);
        }
    }
    /* final labels: in raster order of first appearance */
    memset(final, 0, next * sizeof(int32_t));
    Py_ssize_t n = 0;
    for (Py_ssize_t q = 0; q < nlit; q++) {
        Py_ssize_t at = idx[q];
        int32_t root = find(parent, lab[at]);
        if (final[root] == 0)
            final[root] = (int32_t)++n;
        lab[at] = final[root];
    }
    return n;
}

/* The windows cut from the frame less their level (float32) are lit where above the threshold:
 * lit per pixel, and the lit pixels' flat indices in idx. Returns their number. The values
 * themselves are written out only for the windows whose regions are centroided (plane()): a
 * few of the windows' pixels, which keeps the caches of the caller's next steps. */
#define CUT(T)                                                                              \
    for (Py_ssize_t p = 0; p < k; p++) {                                                    \
        float lv = level[p], th = thr[p];                                                   \
        for (Py_ssize_t i = 0; i < h; i++) {                                                \
            const T *restrict src = (const T *)f->data + (r0[p] + i) * f->cols + c0[p];     \
            Py_ssize_t at = (p * h + i) * w;                                                \
            unsigned char *restrict l = lit + at;                                           \
            unsigned char any = 0;                                                          \
            for (Py_ssize_t j = 0; j < w; j++) {                                            \
                float v = (float)src[j] - lv;                                               \
                unsigned char on = v > th;                                                  \
                l[j] = on;                                                                  \
                any |= on;                                                                  \
            }                                                                               \
            if (any)                                                                        \
                for (Py_ssize_t j = 0; j < w; j++)                                          \
                    if (l[j])                                                               \
                        idx[nlit++] = (int32_t)(at + j);                                    \
        }                                                                                   \
    }                                                                                       \
    break;

static Py_ssize_t cut(const Frame *f, const int64_t *r0, const int64_t *c0, Py_ssize_t k,
                      Py_ssize_t h, Py_ssize_t w, const float *level, const float *thr,
                      unsigned char *lit, int32_t *idx)
{
    Py_ssize_t nlit = 0;
    switch (f->fmt) {
    case 'B': CUT(uint8_t)
    case 'b': CUT(int8_t)
    case 'H': CUT(uint16_t)
    case 'h': CUT(int16_t)
    case 'I': CUT(uint32_t)
    case 'i': CUT(int32_t)
    case 'f': CUT(float)
    default: CUT(double)
    }
    return nlit;
}

/* Window (rows r0.., columns c0.., h x w) of the frame less its level lv: CUT's values. */
#define PLANE(T)                                                                            \
    for (Py_ssize_t i = 0; i < h; i++) {                                                    \
        const T *restrict src = (const T *)f->data + (r0 + i) * f->cols + c0;               \
        float *restrict d = sub + i * w;                                                    \
        for (Py_ssize_t j = 0; j < w; j++)                                                  \
            d[j] = (float)src[j] - lv;                                                      \
    }                                                                                       \
    break;

static void plane(const Frame *f, int64_t r0, int64_t c0, Py_ssize_t h, Py_ssize_t w, float lv,
                  float *sub)
{
    switch (f->fmt) {
    case 'B': PLANE(uint8_t)
    case 'b': PLANE(int8_t)
    case 'H': PLANE(uint16_t)
    case 'h': PLANE(int16_t)
    case 'I': PLANE(uint32_t)
    case 'i': PLANE(int32_t)
    case 'f': PLANE(float)
    default: PLANE(double)
    }
}

typedef struct {
    Py_ssize_t plane, size, a, b, c, d; /* window; pixels; box rows [a, b), cols [c, d) */
    double sum;                         /* background-subtracted counts (float64 sum) */
    float peak;                         /* largest count, as read */
} Region;

/* CoG over the region's box grown by margin (cut at the window), as windows._cogs. */
static void cog(const float *sub, Py_ssize_t h, Py_ssize_t w, const Region *g, Py_ssize_t m,
                double *x, double *y)
{
    Py_ssize_t a = g->a - m > 0 ? g->a - m : 0, b = g->b + m < h ? g->b + m : h;
    Py_ssize_t c = g->c - m > 0 ? g->c - m : 0, d = g->d + m < w ? g->d + m : w;
    double total = 0.0, sx = 0.0, sy = 0.0;
    for (Py_ssize_t i = a; i < b; i++) {
        double row = 0.0;
        for (Py_ssize_t j = c; j < d; j++) {
            double v = (double)sub[i * w + j];
            row += v;
            sx += v * (double)j;
        }
        total += row;
        sy += row * (double)i;
    }
    if (total > 0) {
        *x = sx / total;
        *y = sy / total;
    } else {
        *x = *y = NAN;
    }
}

/* Streak centroid of one region on its window plane, as streak.streak_centroids: the CoG over
 * the pixels within radius of the predicted segment centred on the estimate, moved there,
 * at most 6 times. Returns 0 when no centroid was found. */
static int streak_centroid(const float *sub, Py_ssize_t h, Py_ssize_t w, double x, double y,
                           double stx, double sty, double radius, double *out)
{
    double sx = 0.5 * stx, sy = 0.5 * sty;
    double l2 = 4.0 * (sx * sx + sy * sy);
    if (!(l2 >= 1e-12))
        l2 = 1e-12;
    double a2x = 2 * sx, a2y = 2 * sy, r2 = radius * radius;
    double ox = NAN, oy = NAN, tot = NAN, lx = NAN, ly = NAN;
    int found = 0;
    for (int it = 0; it < 6; it++) {
        Py_ssize_t r0 = (Py_ssize_t)fmax(floor(y - fabs(sy) - radius), 0);
        Py_ssize_t r1 = (Py_ssize_t)fmin(ceil(y + fabs(sy) + radius) + 1, (double)h);
        Py_ssize_t c0 = (Py_ssize_t)fmax(floor(x - fabs(sx) - radius), 0);
        Py_ssize_t c1 = (Py_ssize_t)fmin(ceil(x + fabs(sx) + radius) + 1, (double)w);
        double total = 0.0, mx = 0.0, my = 0.0;
        double bx = x - sx, by = y - sy;
        for (Py_ssize_t i = r0; i < r1; i++) {
            double ay = (double)i - by, row = 0.0;
            for (Py_ssize_t j = c0; j < c1; j++) {
                double ax = (double)j - bx;
                double t = ax * a2x + ay * a2y;
                t /= l2;
                t = t > 0.0 ? t : 0.0;
                t = t < 1.0 ? t : 1.0;
                double ex = ax - t * a2x, ey = ay - t * a2y;
                if (ey * ey + ex * ex <= r2) {
                    double v = (double)sub[i * w + j];
                    row += v;
                    mx += v * (double)j;
                }
            }
            total += row;
            my += row * (double)i;
        }
        if (!(total > 0))
            break;
        double nx = mx / total, ny = my / total;
        ox = nx;
        oy = ny;
        tot = total;
        lx = x;
        ly = y;
        found = 1;
        if (!(hypot(nx - x, ny - y) >= 0.01))
            break;
        x = nx;
        y = ny;
    }
    if (!found)
        return 0;
    /* the box and the spread about the centroid over the capsule it was taken from */
    Py_ssize_t r0 = (Py_ssize_t)fmax(floor(ly - fabs(sy) - radius), 0);
    Py_ssize_t r1 = (Py_ssize_t)fmin(ceil(ly + fabs(sy) + radius) + 1, (double)h);
    Py_ssize_t c0 = (Py_ssize_t)fmax(floor(lx - fabs(sx) - radius), 0);
    Py_ssize_t c1 = (Py_ssize_t)fmin(ceil(lx + fabs(sx) + radius) + 1, (double)w);
    double bx = lx - sx, by = ly - sy, sxx = 0.0, sxy = 0.0, syy = 0.0;
    for (Py_ssize_t i = r0; i < r1; i++) {
        double ay = (double)i - by, dy = (double)i - oy;
        for (Py_ssize_t j = c0; j < c1; j++) {
            double ax = (double)j - bx;
            double t = ax * a2x + ay * a2y;
            t /= l2;
            t = t > 0.0 ? t : 0.0;
            t = t < 1.0 ? t : 1.0;
            double ex = ax - t * a2x, ey = ay - t * a2y;
            if (ey * ey + ex * ex <= r2) {
                double dx = (double)j - ox;
                sxx += dx * dx;
                sxy += dx * dy;
                syy += dy * dy;
            }
        }
    }
    out[X] = ox;
    out[Y] = oy;
    out[COUNTS] = tot;
    out[BOX_R0] = (double)r0;
    out[BOX_R1] = (double)r1;
    out[BOX_C0] = (double)c0;
    out[BOX_C1] = (double)c1;
    out[SXX] = sxx;
    out[SXY] = out[SYX] = sxy;
    out[SYY] = syy;
    return 1;
}

static int check(Py_buffer *b, Py_ssize_t bytes, const char *what)
{
    if (b->len < bytes) {
        PyErr_Format(PyExc_ValueError, "_windowc: %s holds %zd bytes, needs %zd", what, b->len,
                     bytes);
        return 0;
    }
    return 1;
}

/* detect_windows(image, fmt, rows, cols, r0, c0, k, h, w, level, threshold, connectivity,
 *                min_pixels, min_counts, margin, streaks, has_streaks, sigma_px, out, cap)
 * -> (regions, rows written). out: float64 (cap, NCOL); see the module comment. */
static PyObject *detect_windows(PyObject *self, PyObject *args)
{
    Py_buffer imb, r0b, c0b, levb, thrb, stb, outb;
    const char *fmt;
    Py_ssize_t rows, cols, k, h, w, min_pixels, margin, cap;
    int connectivity, has_streaks;
    double min_counts, sigma;
    if (!PyArg_ParseTuple(args, "y*snny*y*nnny*y*indny*idw*n", &imb, &fmt, &rows, &cols, &r0b,
                          &c0b, &k, &h, &w, &levb, &thrb, &connectivity, &min_pixels,
                          &min_counts, &margin, &stb, &has_streaks, &sigma, &outb, &cap))
        return NULL;
    PyObject *result = NULL;
    Region *reg = NULL;
    Py_ssize_t npix = k * h * w, size = item_size(fmt[0]);
    if (size == 0 || fmt[1] != '\0') {
        PyErr_Format(PyExc_ValueError, "_windowc: unsupported pixel type %s", fmt);
        goto done;
    }
    if (!check(&imb, rows * cols * size, "image") || !check(&r0b, k * 8, "r0") ||
        !check(&c0b, k * 8, "c0") || !check(&levb, k * 4, "level") ||
        !check(&thrb, k * 4, "threshold") || !check(&outb, cap * NCOL * 8, "out") ||
        (has_streaks && !check(&stb, k * 16, "streaks")))
        goto done;
    const int64_t *r0 = r0b.buf, *c0 = c0b.buf;
    const float *level = levb.buf, *thr = thrb.buf;
    const double *streaks = stb.buf;
    double *out = outb.buf;
    for (Py_ssize_t p = 0; p < k; p++) {
        if (r0[p] < 0 || c0[p] < 0 || r0[p] + h > rows || c0[p] + w > cols) {
            PyErr_SetString(PyExc_ValueError, "_windowc: a window lies off the frame");
            goto done;
        }
    }
    Frame frame = {imb.buf, fmt[0], cols};
    if (npix >= INT32_MAX || !reserve(npix)) {
        PyErr_NoMemory();
        goto done;
    }
    float *sub = g_sub; /* one window's values at a time (plane()) */
    int32_t *lab = g_lab, *idx = g_idx;
    Py_ssize_t nlit = cut(&frame, r0, c0, k, h, w, level, thr, g_lit, idx);
    Py_ssize_t n = label_windows(g_lit, lab, idx, nlit, h, w, connectivity != 4);
    reg = calloc(n + 1, sizeof(Region));
    if (reg == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t q = 1; q <= n; q++) {
        reg[q].a = reg[q].c = PY_SSIZE_T_MAX;
        reg[q].peak = -INFINITY;
    }
    /* each region's pixels, counts (summed in raster order, as np.bincount), box and peak */
    for (Py_ssize_t q = 0; q < nlit; q++) {
        Py_ssize_t at = idx[q], p = at / (h * w), rest = at % (h * w), i = rest / w, j = rest % w;
        Region *g = &reg[lab[at]];
        g->plane = p;
        g->size++;
        float v = pixel(&frame, r0[p] + i, c0[p] + j);
        g->sum += (double)(v - level[p]); /* the value CUT thresholded */
        if (i < g->a) g->a = i;
        if (i + 1 > g->b) g->b = i + 1;
        if (j < g->c) g->c = j;
        if (j + 1 > g->d) g->d = j + 1;
        if (v > g->peak) g->peak = v;
    }
    double reach = 2.5 * sigma + 1.0;
    Py_ssize_t m = 0, filled = -1; /* the window whose values sub holds */
    for (Py_ssize_t q = 1; q <= n; q++) {
        Region *g = &reg[q];
        Py_ssize_t p = g->plane;
        if (!(g->size >= min_pixels && g->sum >= min_counts))
            continue;
        /* a star cut by the window's edge (not the frame's) has a biased centroid: dropped */
        if ((g->a == 0 && 0 < r0[p]) || (g->b == h && r0[p] + h < rows) ||
            (g->c == 0 && 0 < c0[p]) || (g->d == w && c0[p] + w < cols))
            continue;
        if (m == cap) {
            PyErr_SetString(PyExc_ValueError, "_windowc: out holds too few rows");
            goto done;
        }
        double *row = out + m * NCOL;
        if (filled != p) {
            plane(&frame, r0[p], c0[p], h, w, level[p], sub);
            filled = p;
        }
        double x, y;
        cog(sub, h, w, g, margin, &x, &y);
        row[X] = x;
        row[Y] = y;
        row[COUNTS] = g->sum;
        row[BOX_R0] = (double)g->a;
        row[BOX_R1] = (double)g->b;
        row[BOX_C0] = (double)g->c;
        row[BOX_C1] = (double)g->d;
        row[SXX] = row[SXY] = row[SYX] = row[SYY] = NAN;
        if (!isfinite(x))
            continue;
        if (has_streaks) {
            double stx = streaks[2 * p], sty = streaks[2 * p + 1];
            if (hypot(stx, sty) >= 2.0 * sigma &&
                streak_centroid(sub, h, w, x, y, stx, sty, reach, row)) {
                /* a streak running off the frame: its centroid is pulled inwards */
                double fx = row[X] + (double)c0[p], fy = row[Y] + (double)r0[p];
                double hx = 0.5 * fabs(stx) + reach, hy = 0.5 * fabs(sty) + reach;
                if (!((hx <= fx) && (fx <= (double)(cols - 1) - hx) && (hy <= fy) &&
                      (fy <= (double)(rows - 1) - hy)))
                    continue;
            }
        }
        row[X] += (double)c0[p];
        row[Y] += (double)r0[p];
        row[PIXELS] = (double)g->size;
        row[PEAK] = (double)g->peak;
        row[BOX_R0] += (double)r0[p];
        row[BOX_R1] += (double)r0[p];
        row[BOX_C0] += (double)c0[p];
        row[BOX_C1] += (double)c0[p];
        m++;
    }
    result = Py_BuildValue("nn", n, m);
done:
    free(reg);
    PyBuffer_Release(&imb);
    PyBuffer_Release(&r0b);
    PyBuffer_Release(&c0b);
    PyBuffer_Release(&levb);
    PyBuffer_Release(&thrb);
    PyBuffer_Release(&stb);
    PyBuffer_Release(&outb);
    return result;
}

static int cmp_i64(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

/* The distinct values of v[0..n) ascending, in place; returns their number. */
static Py_ssize_t distinct(int64_t *v, Py_ssize_t n)
{
    qsort(v, n, sizeof(int64_t), cmp_i64);
    Py_ssize_t m = 0;
    for (Py_ssize_t i = 0; i < n; i++)
        if (m == 0 || v[i] != v[m - 1])
            v[m++] = v[i];
    return m;
}

static Py_ssize_t find_edge(const int64_t *e, Py_ssize_t n, int64_t x)
{
    Py_ssize_t lo = 0, hi = n;
    while (lo < hi) {
        Py_ssize_t mid = (lo + hi) / 2;
        if (e[mid] < x)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* union_area(boxes, k) -> pixels covered by the union of the k boxes (row0, row1, col0, col1;
 * int64, half-open), exactly: the cells between the boxes' edges, as windows.union_area. */
static PyObject *union_area(PyObject *self, PyObject *args)
{
    Py_buffer bb;
    Py_ssize_t k;
    if (!PyArg_ParseTuple(args, "y*n", &bb, &k))
        return NULL;
    PyObject *result = NULL;
    int64_t *rows = NULL, *cols = NULL;
    unsigned char *covered = NULL;
    if (!check(&bb, k * 32, "boxes"))
        goto done;
    const int64_t *b = bb.buf;
    rows = malloc((2 * k + 1) * sizeof(int64_t));
    cols = malloc((2 * k + 1) * sizeof(int64_t));
    if (!rows || !cols) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t i = 0; i < k; i++) {
        rows[2 * i] = b[4 * i];
        rows[2 * i + 1] = b[4 * i + 1];
        cols[2 * i] = b[4 * i + 2];
        cols[2 * i + 1] = b[4 * i + 3];
    }
    Py_ssize_t nr = distinct(rows, 2 * k), nc = distinct(cols, 2 * k);
    covered = calloc((nr + 1) * (nc + 1), 1);
    if (covered == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t i = 0; i < k; i++) {
        Py_ssize_t i0 = find_edge(rows, nr, b[4 * i]), i1 = find_edge(rows, nr, b[4 * i + 1]);
        Py_ssize_t j0 = find_edge(cols, nc, b[4 * i + 2]), j1 = find_edge(cols, nc, b[4 * i + 3]);
        for (Py_ssize_t r = i0; r < i1; r++)
            memset(covered + r * nc + j0, 1, j1 > j0 ? j1 - j0 : 0);
    }
    long long area = 0;
    for (Py_ssize_t r = 0; r + 1 < nr; r++)
        for (Py_ssize_t c = 0; c + 1 < nc; c++)
            if (covered[r * nc + c])
                area += (long long)(rows[r + 1] - rows[r]) * (cols[c + 1] - cols[c]);
    result = PyLong_FromLongLong(area);
done:
    free(covered);
    free(rows);
    free(cols);
    PyBuffer_Release(&bb);
    return result;
}

/* apart(x, y, order, n, keep) -> m: the rows order[0..n) in turn, kept when at least 2 px
 * (math.hypot) from every row kept before; keep[0..m) their positions in order, as
 * windows._detections. */
static PyObject *apart(PyObject *self, PyObject *args)
{
    Py_buffer xb, yb, ob, kb;
    Py_ssize_t n;
    if (!PyArg_ParseTuple(args, "y*y*y*nw*", &xb, &yb, &ob, &n, &kb))
        return NULL;
    PyObject *result = NULL;
    if (check(&xb, n * 8, "x") && check(&yb, n * 8, "y") && check(&ob, n * 8, "order") &&
        check(&kb, n * 8, "keep")) {
        const double *x = xb.buf, *y = yb.buf;
        const int64_t *order = ob.buf;
        int64_t *keep = kb.buf;
        Py_ssize_t m = 0;
        for (Py_ssize_t i = 0; i < n; i++) {
            double xi = x[order[i]], yi = y[order[i]];
            int ok = 1;
            for (Py_ssize_t j = 0; j < m && ok; j++)
                ok = hypot(xi - x[order[keep[j]]], yi - y[order[keep[j]]]) >= 2.0;
            if (ok)
                keep[m++] = i;
        }
        result = PyLong_FromSsize_t(m);
    }
    PyBuffer_Release(&xb);
    PyBuffer_Release(&yb);
    PyBuffer_Release(&ob);
    PyBuffer_Release(&kb);
    return result;
}

/* count_inside(boxes, x, y, k, n) -> how many of the n points (x, y), rounded half to even
 * (np.rint), lie in one of the k boxes (row0, row1, col0, col1; half-open), as
 * window_kernels.count_inside_numpy. */
static PyObject *count_inside(PyObject *self, PyObject *args)
{
    Py_buffer bb, xb, yb;
    Py_ssize_t k, n;
    if (!PyArg_ParseTuple(args, "y*y*y*nn", &bb, &xb, &yb, &k, &n))
        return NULL;
    PyObject *result = NULL;
    if (check(&bb, k * 32, "boxes") && check(&xb, n * 8, "x") && check(&yb, n * 8, "y")) {
        const int64_t *box = bb.buf;
        const double *x = xb.buf, *y = yb.buf;
        Py_ssize_t count = 0;
        for (Py_ssize_t i = 0; i < n; i++) {
            double xi = nearbyint(x[i]), yi = nearbyint(y[i]);
            for (Py_ssize_t j = 0; j < k; j++) {
                const int64_t *b = box + 4 * j;
                if (yi >= (double)b[0] && yi < (double)b[1] && xi >= (double)b[2] &&
                    xi < (double)b[3]) {
                    count++;
                    break;
                }
            }
        }
        result = PyLong_FromSsize_t(count);
    }
    PyBuffer_Release(&bb);
    PyBuffer_Release(&xb);
    PyBuffer_Release(&yb);
    return result;
}

static PyMethodDef methods[] = {
    {"detect_windows", detect_windows, METH_VARARGS,
     "Detect and centroid the stars of tracking windows (see _windowc.c)."},
    {"union_area", union_area, METH_VARARGS, "Pixels covered by a union of boxes."},
    {"apart", apart, METH_VARARGS, "Rows kept at least 2 px from those kept before."},
    {"count_inside", count_inside, METH_VARARGS, "Points inside a union of boxes."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_windowc", NULL, -1, methods};

PyMODINIT_FUNC PyInit__windowc(void) { return PyModule_Create(&module); }
