/* Compiled core of lost-in-space identification by 4-star geometric hashing.
 *
 * starsense.identify.hashing.HashIdentifier looks the patterns of the brightest detections up
 * in the database's sorted hash index and verifies the candidates. Its NumPy form does each
 * pattern, each look-up and each verification step in a few dozen array operations on 4 to 60
 * rows, whose cost is NumPy's per-call overhead, not the arithmetic. This kernel runs the same
 * algorithm for one frame in one call (identify):
 *
 *   - the 4-star patterns of the brightest detections, breadth first (patterns.
 *     breadth_first_combinations), each in canonical order (patterns.order_by_centroid_distance)
 *     with its five edge ratios and largest edge (patterns.edge_ratios): describe();
 *   - the hash keys of the box ratios +- pattern_max_error, probed in the sorted key array
 *     (binary search), candidates within the error kept, nearest first (HashIdentifier._lookup):
 *     lookup();
 *   - the scale test of a known field, then the verification of each candidate as
 *     verify.Verifier does it, for a known field or with the scale of the tangent plane fitted
 *     for an unknown one (attitude from the pairs, nearest catalogue star
 *     of every detection within the match radius, refit, two passes with a radius from the
 *     residuals; a known field whose first such radius is not inside the match radius is
 *     refused, as the Verifier refuses it): verify().
 *
 * The acceptance decision (the false-match probability and its threshold) is not made here:
 * verify() calls back the Python callable it is given, Verifier.accept, with (detections,
 * matched, hypothesis stars, p_single) and takes its (p_false, accepted).
 *
 * Arithmetic: the descriptors and the look-up are the NumPy form's operations in the same order
 * (the centroid summed star by star, squared norms in einsum's order), so the canonical order of
 * a pattern's stars is the NumPy form's bit for bit, and its ratios but for asin, which NumPy
 * may take from its own vectorised routine (a few ulp).
 * The attitude is Davenport's q method (the largest eigenvector of the 4x4 K matrix, cyclic
 * Jacobi) where the NumPy form takes the SVD: the same rotation to ~1e-13 rad. Catalogue stars
 * of a field come from a grid on the cube [-1, 1]^3 (hash_kernels.star_grid) where the NumPy
 * form asks a k-d tree; the stars inside the cone are the same set. Decisions therefore agree
 * except where a value falls within rounding of a threshold (tests/identify/
 * test_hash_kernel.py). Built with -ffp-contract=off: no fused multiply-add.
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
#include <time.h>

#define K 4         /* stars per pattern */
#define NR 5        /* edge ratios per pattern */
#define MAXDET 1024 /* detections taken part in verification at most */

enum { B_KEYS, B_RATIOS, B_LARGEST, B_PATTERNS, B_STARS, B_CSTART, B_CSTARS, B_CVEC, B_DIR, NBUF };

typedef struct {
    Py_buffer buf[NBUF];
    const int64_t *keys;
    const float *ratios;
    const float *largest;
    const int32_t *patterns;
    const double *stars;
    const int64_t *cell_start;
    const int64_t *cell_stars;
    const double *cell_vectors; /* stars[cell_stars]: a cell's stars side by side */
    const int64_t *dir;         /* keys[dir[b]:dir[b + 1]] are the keys in [b, b + 1) * dir_step */
    int64_t dir_step, n_dir;
    Py_ssize_t n_patterns, n_stars;
    int grid;
    double cell;
    int n_bins, max_cand, max_det;
    double max_error, scale_tol, match_radius;
} Tables;

/* growable arrays ----------------------------------------------------------------------- */

typedef struct {
    void *p;
    size_t n, cap, item;
} Vec;

static int vec_reserve(Vec *v, size_t n)
{
    if (n <= v->cap)
        return 0;
    size_t cap = v->cap ? v->cap : 64;
    while (cap < n)
        cap *= 2;
    void *p = realloc(v->p, cap * v->item);
    if (p == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    v->p = p;
    v->cap = cap;
    return 0;
}

static void vec_free(Vec *v)
{
    free(v->p);
    v->p = NULL;
    v->n = v->cap = 0;
}

/* pattern descriptors ------------------------------------------------------------------- */

static const int EDGE[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};

static inline double dot3(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* x . x as NumPy's einsum("...i,...i->...") adds three products on x86-64 (two-lane vectors:
 * lane 0 takes x0 x0 and x2 x2, lane 1 x1 x1, then the lanes are added). */
static inline double einsum_sq3(const double *x)
{
    return (x[0] * x[0] + x[2] * x[2]) + x[1] * x[1];
}

/* Describe the pattern of detections idx (rows of v): its stars in canonical order (det), its
 * edge ratios and largest edge. Returns 0 for a pattern without a shape (a zero edge). */
static int describe(const double *v, const int64_t idx[K], int64_t det[K], double ratios[NR],
                    double *largest)
{
    const double *p[K];
    double c[3], d2[K], e[6];
    int order[K];
    for (int k = 0; k < K; k++)
        p[k] = v + 3 * idx[k];
    for (int i = 0; i < 3; i++)
        c[i] = ((p[0][i] + p[1][i]) + p[2][i]) + p[3][i];
    double cn = sqrt(einsum_sq3(c));
    for (int i = 0; i < 3; i++)
        c[i] /= cn;
    for (int k = 0; k < K; k++) {
        double d[3] = {p[k][0] - c[0], p[k][1] - c[1], p[k][2] - c[2]};
        d2[k] = einsum_sq3(d);
    }
    for (int k = 0; k < K; k++) { /* stable insertion sort by d2 (NaN last, as argsort) */
        int j = k;
        while (j > 0 && (d2[order[j - 1]] > d2[k] || (isnan(d2[order[j - 1]]) && !isnan(d2[k])))) {
            order[j] = order[j - 1];
            j--;
        }
        order[j] = k;
    }
    for (int k = 0; k < K; k++)
        det[k] = idx[order[k]];
    for (int q = 0; q < 6; q++) {
        const double *a = p[EDGE[q][0]], *b = p[EDGE[q][1]];
        double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
        double h = sqrt(einsum_sq3(d)) / 2.0;
        h = h < 0.0 ? 0.0 : (h > 1.0 ? 1.0 : h);
        e[q] = 2.0 * asin(h);
    }
    for (int q = 1; q < 6; q++) { /* ascending */
        double x = e[q];
        int j = q;
        while (j > 0 && e[j - 1] > x) {
            e[j] = e[j - 1];
            j--;
        }
        e[j] = x;
    }
    *largest = e[5];
    int ok = e[5] > 0.0;
    for (int q = 0; q < NR; q++) {
        ratios[q] = e[q] / e[5];
        ok = ok && isfinite(ratios[q]);
    }
    return ok;
}

/* hash look-up -------------------------------------------------------------------------- */

typedef struct {
    int64_t index;
    double diff;
    Py_ssize_t pos; /* order of collection: ties of diff keep it (a stable sort) */
} Cand;

static int cand_cmp(const void *a, const void *b)
{
    const Cand *x = a, *y = b;
    if (x->diff != y->diff)
        return x->diff < y->diff ? -1 : 1;
    return (x->pos > y->pos) - (x->pos < y->pos);
}

static Py_ssize_t lower_bound(const int64_t *k, Py_ssize_t n, int64_t key)
{
    Py_ssize_t lo = 0, hi = n;
    while (lo < hi) {
        Py_ssize_t mid = lo + (hi - lo) / 2;
        if (k[mid] < key)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

#if defined(__GNUC__) || defined(__clang__)
#define PREFETCH(p) __builtin_prefetch(p)
#else
#define PREFETCH(p) ((void)0)
#endif

#define KEY_CHUNK 64

/* Append the candidates of the keys (in their order) to out: the directory entries of all of
 * them are asked for first, then the middle of their buckets, then the buckets are searched,
 * so that their cache misses overlap. */
static int add_keys(const Tables *t, const double r[NR], const int64_t *keys, int nk, Vec *out)
{
    Py_ssize_t lo[KEY_CHUNK], hi[KEY_CHUNK];
    for (int i = 0; i < nk; i++) {
        int64_t b = keys[i] / t->dir_step;
        if (b >= 0 && b < t->n_dir)
            PREFETCH(t->dir + b);
    }
    for (int i = 0; i < nk; i++) {
        int64_t b = keys[i] / t->dir_step;
        lo[i] = hi[i] = 0;
        if (b >= 0 && b < t->n_dir) {
            lo[i] = t->dir[b];
            hi[i] = t->dir[b + 1];
            PREFETCH(t->keys + lo[i] + (hi[i] - lo[i]) / 2);
        }
    }
    for (int i = 0; i < nk; i++) {
        Py_ssize_t a = lo[i] + lower_bound(t->keys + lo[i], hi[i] - lo[i], keys[i]);
        for (Py_ssize_t c = a; c < t->n_patterns && t->keys[c] == keys[i]; c++) {
            double diff = 0.0;
            const float *pr = t->ratios + NR * c;
            int q = 0;
            for (; q < NR; q++) { /* the largest difference; out at the first beyond the error */
                double x = fabs((double)pr[q] - r[q]);
                if (!(x <= t->max_error))
                    break;
                diff = x > diff ? x : diff;
            }
            if (q < NR)
                continue;
            if (vec_reserve(out, out->n + 1) < 0)
                return -1;
            Cand *cd = (Cand *)out->p + out->n;
            cd->index = c;
            cd->diff = diff;
            cd->pos = (Py_ssize_t)out->n;
            out->n++;
        }
    }
    return 0;
}

/* The database patterns whose hash bins overlap r +- max_error and whose ratios lie within
 * it, nearest first, into out (Cand). Keys in the NumPy form's order: itertools.product over
 * the ratios' bin ranges, the last ratio fastest. */
static int lookup(const Tables *t, const double r[NR], Vec *out)
{
    int64_t lo[NR], hi[NR], w[NR], bin[NR], keys[KEY_CHUNK];
    double nb = (double)t->n_bins;
    int nk = 0, done = 0;
    out->n = 0;
    for (int q = 0; q < NR; q++) {
        double a = (r[q] - t->max_error) * nb, b = (r[q] + t->max_error) * nb;
        a = fmin(fmax(a, 0.0), nb - 1.0);
        b = fmin(fmax(b, 0.0), nb - 1.0);
        lo[q] = (int64_t)a;
        hi[q] = (int64_t)b;
        w[q] = q ? w[q - 1] * t->n_bins : 1;
        bin[q] = lo[q];
    }
    while (!done) {
        int64_t key = 0;
        for (int q = 0; q < NR; q++)
            key += bin[q] * w[q];
        keys[nk++] = key;
        int q = NR - 1;
        while (q >= 0 && bin[q] == hi[q]) {
            bin[q] = lo[q];
            q--;
        }
        if (q < 0)
            done = 1;
        else
            bin[q]++;
        if (nk == KEY_CHUNK || done) {
            if (add_keys(t, r, keys, nk, out) < 0)
                return -1;
            nk = 0;
        }
    }
    if (out->n > 1)
        qsort(out->p, out->n, sizeof(Cand), cand_cmp);
    return 0;
}

/* attitude: Davenport's q method ---------------------------------------------------------- */

/* Eigenvector of the largest eigenvalue of the symmetric 4x4 a (destroyed), cyclic Jacobi. */
static void largest_eigenvector(double a[4][4], double q[4])
{
    double v[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
    for (int sweep = 0; sweep < 50; sweep++) {
        double off = 0.0, diag = 0.0;
        for (int i = 0; i < 4; i++) {
            diag += a[i][i] * a[i][i];
            for (int j = i + 1; j < 4; j++)
                off += a[i][j] * a[i][j];
        }
        if (off <= 1e-36 * diag)
            break;
        for (int p = 0; p < 4; p++) {
            for (int r = p + 1; r < 4; r++) {
                if (a[p][r] == 0.0)
                    continue;
                double theta = (a[r][r] - a[p][p]) / (2.0 * a[p][r]);
                double tt = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                double c = 1.0 / sqrt(tt * tt + 1.0), s = tt * c;
                for (int k = 0; k < 4; k++) { /* columns p, r */
                    double akp = a[k][p], akr = a[k][r];
                    a[k][p] = c * akp - s * akr;
                    a[k][r] = s * akp + c * akr;
                }
                for (int k = 0; k < 4; k++) { /* rows p, r */
                    double apk = a[p][k], ark = a[r][k];
                    a[p][k] = c * apk - s * ark;
                    a[r][k] = s * apk + c * ark;
                }
                a[p][r] = a[r][p] = 0.0;
                for (int k = 0; k < 4; k++) {
                    double vkp = v[k][p], vkr = v[k][r];
                    v[k][p] = c * vkp - s * vkr;
                    v[k][r] = s * vkp + c * vkr;
                }
            }
        }
    }
    int best = 0;
    for (int i = 1; i < 4; i++)
        if (a[i][i] > a[best][best])
            best = i;
    for (int i = 0; i < 4; i++)
        q[i] = v[i][best];
}

/* The attitude matrix R (body ~ R ref, row-major) of m pairs (Wahba, equal weights) and the
 * residual angles. body: detection directions of det; ref: database stars of cat. */
static void fit_body(const Tables *t, const double *body, const int64_t *cat, int m, double R[9],
                     double *resid)
{
    double B[3][3] = {{0}};
    for (int k = 0; k < m; k++) {
        const double *b = body + 3 * k, *r = t->stars + 3 * cat[k];
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                B[i][j] += b[i] * r[j];
    }
    double sigma = B[0][0] + B[1][1] + B[2][2];
    double z[3] = {B[1][2] - B[2][1], B[2][0] - B[0][2], B[0][1] - B[1][0]};
    double Km[4][4];
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++)
            Km[i][j] = B[i][j] + B[j][i] - (i == j ? sigma : 0.0);
        Km[i][3] = Km[3][i] = z[i];
    }
    Km[3][3] = sigma;
    double q[4];
    largest_eigenvector(Km, q);
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double x = q[0] / n, y = q[1] / n, w = q[2] / n, s = q[3] / n;
    /* A(q) = (s^2 - |v|^2) I + 2 v v^T - 2 s [v x], v = (x, y, w) */
    double d = s * s - (x * x + y * y + w * w);
    R[0] = d + 2 * x * x;
    R[1] = 2 * x * y + 2 * s * w;
    R[2] = 2 * x * w - 2 * s * y;
    R[3] = 2 * y * x - 2 * s * w;
    R[4] = d + 2 * y * y;
    R[5] = 2 * y * w + 2 * s * x;
    R[6] = 2 * w * x + 2 * s * y;
    R[7] = 2 * w * y - 2 * s * x;
    R[8] = d + 2 * w * w;
    for (int k = 0; k < m; k++) {
        const double *b = body + 3 * k, *r = t->stars + 3 * cat[k];
        double ch2 = 0.0;
        for (int i = 0; i < 3; i++) {
            double e = (R[3 * i] * r[0] + R[3 * i + 1] * r[1] + R[3 * i + 2] * r[2]) - b[i];
            ch2 += e * e;
        }
        resid[k] = 2.0 * asin(fmin(sqrt(ch2) / 2.0, 1.0));
    }
}

/* Camera directions of tangent-plane points (x/z, y/z) times scale, as
 * geometry.projection.tangent_to_vectors computes them. */
static void scaled_vectors(const double *tan, int n, double scale, double *out)
{
    for (int i = 0; i < n; i++) {
        double x = tan[2 * i] * scale, y = tan[2 * i + 1] * scale;
        double norm = sqrt((x * x + y * y) + 1.0);
        out[3 * i] = x / norm;
        out[3 * i + 1] = y / norm;
        out[3 * i + 2] = 1.0 / norm;
    }
}

/* fit() with the pairs' detections taken from vs (all detections). */
static void fit(const Tables *t, const double *vs, const int64_t *det, const int64_t *cat, int m,
                double R[9], double *resid)
{
    double body[3 * MAXDET];
    for (int k = 0; k < m; k++)
        memcpy(body + 3 * k, vs + 3 * det[k], 3 * sizeof(double));
    fit_body(t, body, cat, m, R, resid);
}

/* The attitude and the scale of the tangent plane (Verifier._fit with fit_scale): four rounds of
 * attitude at the scale, then the scale that maps the detections' tangent points onto the
 * stars' (least squares), then the attitude at the last scale. */
static void fit_scaled(const Tables *t, const double *tan, const int64_t *det, const int64_t *cat,
                       int m, double *scale, double R[9], double *resid)
{
    double td[2 * MAXDET], body[3 * MAXDET], denom = 0.0;
    for (int k = 0; k < m; k++) {
        td[2 * k] = tan[2 * det[k]];
        td[2 * k + 1] = tan[2 * det[k] + 1];
        denom += td[2 * k] * td[2 * k] + td[2 * k + 1] * td[2 * k + 1];
    }
    for (int it = 0; it < 4; it++) {
        scaled_vectors(td, m, *scale, body);
        fit_body(t, body, cat, m, R, resid);
        if (denom <= 0.0)
            break;
        double num = 0.0;
        for (int k = 0; k < m; k++) {
            const double *r = t->stars + 3 * cat[k];
            double c[3];
            for (int i = 0; i < 3; i++)
                c[i] = R[3 * i] * r[0] + R[3 * i + 1] * r[1] + R[3 * i + 2] * r[2];
            num += td[2 * k] * (c[0] / c[2]) + td[2 * k + 1] * (c[1] / c[2]);
        }
        *scale = num / denom;
    }
    scaled_vectors(td, m, *scale, body);
    fit_body(t, body, cat, m, R, resid);
}

/* matching ------------------------------------------------------------------------------ */

typedef struct {
    int d;
    Py_ssize_t c; /* position in the near list */
    double chord2;
} Pair;

static int pair_cmp(const void *a, const void *b)
{
    const Pair *x = a, *y = b;
    if (x->chord2 != y->chord2)
        return x->chord2 < y->chord2 ? -1 : 1;
    if (x->d != y->d)
        return x->d - y->d;
    return (x->c > y->c) - (x->c < y->c);
}

typedef struct {
    Vec sky;    /* int64 star indices near the first attitude of a hypothesis */
    Vec near;   /* int64 star indices in the cone */
    Vec cam;    /* double[3] of each, camera frame */
    Vec pairs;  /* Pair */
    Vec used;   /* char per near star */
    double sky_centre[3], sky_cos_reach;
} Scratch;

/* The detections of a frame: directions (unit, brightest first) and their order in x. */
typedef struct {
    const double *vs;
    int n;
    double max_off;
    double xs[MAXDET]; /* x of the detections, ascending */
    int xi[MAXDET];    /* which detection each is */
    double tan[2 * MAXDET];   /* unknown field: (x/z, y/z) of the detections */
    double scaled[3 * MAXDET]; /* unknown field: their directions at the current scale */
} Frame;

/* Take vs as the frame's directions: index them by x, and their largest angle off axis. */
static void frame_init(Frame *f, const double *vs, int n)
{
    double zmin = 1.0;
    f->vs = vs;
    f->n = n;
    for (int i = 0; i < n; i++) {
        double x = vs[3 * i];
        int j = i;
        while (j > 0 && f->xs[j - 1] > x) {
            f->xs[j] = f->xs[j - 1];
            f->xi[j] = f->xi[j - 1];
            j--;
        }
        f->xs[j] = x;
        f->xi[j] = i;
        zmin = fmin(zmin, vs[3 * i + 2]);
    }
    f->max_off = acos(fmin(fmax(zmin, -1.0), 1.0));
}

/* The first index of the ascending x[0..n) with x[i] >= key (n if none): a binary search
 * without branches on the data (conditional moves), which a frame's few dozen detections
 * searched for every star of the field would otherwise mispredict half the time. */
static inline int first_at_least(const double *x, int n, double key)
{
    if (n <= 0)
        return 0;
    const double *b = x;
    int len = n;
    while (len > 1) {
        int half = len / 2;
        b = b[half] < key ? b + half : b;
        len -= half;
    }
    return (int)(b - x) + (b[0] < key);
}

/* The database stars within `reach` of `centre` (Verifier's _Field: fetched once per
 * hypothesis, filtered to the cone of each later attitude). */
static int fetch_sky(const Tables *t, Scratch *s, const double centre[3], double reach)
{
    reach = fmin(reach, M_PI);
    double cosr = cos(reach);
    double chord = 2.0 * sin(reach / 2.0) * (1.0 + 1e-9) + 1e-12;
    int lo[3], hi[3];
    for (int i = 0; i < 3; i++) {
        lo[i] = (int)floor((centre[i] - chord + 1.0) / t->cell);
        hi[i] = (int)floor((centre[i] + chord + 1.0) / t->cell);
        lo[i] = lo[i] < 0 ? 0 : (lo[i] >= t->grid ? t->grid - 1 : lo[i]);
        hi[i] = hi[i] < 0 ? 0 : (hi[i] >= t->grid ? t->grid - 1 : hi[i]);
        s->sky_centre[i] = centre[i];
    }
    s->sky_cos_reach = cosr;
    s->sky.n = 0;
    for (int a = lo[0]; a <= hi[0]; a++)
        for (int b = lo[1]; b <= hi[1]; b++)
            for (int c = lo[2]; c <= hi[2]; c++) {
                Py_ssize_t cell = ((Py_ssize_t)a * t->grid + b) * t->grid + c;
                for (int64_t j = t->cell_start[cell]; j < t->cell_start[cell + 1]; j++) {
                    /* the tree's test is on the chord; 1e-12 of margin, the cone test decides */
                    if (dot3(t->cell_vectors + 3 * j, centre) >= cosr - 1e-12) {
                        if (vec_reserve(&s->sky, s->sky.n + 1) < 0)
                            return -1;
                        ((int64_t *)s->sky.p)[s->sky.n++] = t->cell_stars[j];
                    }
                }
            }
    return 0;
}

/* One-to-one nearest pairs (detection, star) within radius among the stars within cone_rad of
 * the boresight R[6..8]; p_single as Verifier._match. Pairs into det_m/cat_m (sorted by
 * detection), their number into *m. */
static int match(const Tables *t, Scratch *s, const Frame *f, const double R[9], double cone_rad,
                 double radius, int64_t *det_m, int64_t *cat_m, int *m, double *p_single)
{
    const double *centre = R + 6, *vs = f->vs;
    double cone = fmin(cone_rad, M_PI / 2.0), cosc = cos(cone);
    if (dot3(centre, s->sky_centre) < cos(fmax(acos(s->sky_cos_reach) - cone, 0.0))) {
        /* moved too far for the fetched stars (never seen in practice): fetch again */
        if (fetch_sky(t, s, centre, cone + 0.05) < 0)
            return -1;
    }
    const int64_t *sky = s->sky.p;
    s->near.n = 0;
    if (vec_reserve(&s->near, s->sky.n) < 0)
        return -1;
    int64_t *near = s->near.p;
    for (size_t j = 0; j < s->sky.n; j++)
        if (dot3(t->stars + 3 * sky[j], centre) >= cosc)
            near[s->near.n++] = sky[j];
    size_t nn = s->near.n;
    double solid = 2.0 * M_PI * (1.0 - cos(cone_rad));
    *p_single = (double)nn * M_PI * (radius * radius) / solid; /* radius**2: one rounding */
    *m = 0;
    if (nn == 0)
        return 0;
    if (vec_reserve(&s->cam, nn) < 0 || vec_reserve(&s->used, nn) < 0)
        return -1;
    double *cam = s->cam.p;
    double limit = 2.0 * sin(radius / 2.0), lim2 = limit * limit;
    double reach = limit * (1.0 + 1e-9) + 1e-12; /* |dx| <= chord: a window in x */
    int dcount[MAXDET] = {0};
    int contested = 0;
    s->pairs.n = 0;
    for (size_t j = 0; j < nn; j++) {
        const double *st = t->stars + 3 * near[j];
        double *cj = cam + 3 * j;
        for (int i = 0; i < 3; i++)
            cj[i] = R[3 * i] * st[0] + R[3 * i + 1] * st[1] + R[3 * i + 2] * st[2];
        int lo = first_at_least(f->xs, f->n, cj[0] - reach);
        int here = 0;
        for (int i = lo; i < f->n && f->xs[i] <= cj[0] + reach; i++) {
            int d = f->xi[i];
            double ch2 = 2.0 - 2.0 * dot3(vs + 3 * d, cj);
            if (!(ch2 <= lim2))
                continue;
            if (vec_reserve(&s->pairs, s->pairs.n + 1) < 0)
                return -1;
            Pair *p = (Pair *)s->pairs.p + s->pairs.n++;
            p->d = d;
            p->c = (Py_ssize_t)j;
            p->chord2 = ch2;
            contested |= here++ > 0 || dcount[d]++ > 0;
        }
    }
    Pair *pairs = s->pairs.p;
    Py_ssize_t np_ = (Py_ssize_t)s->pairs.n;
    if (contested) { /* nearest pairs first, each detection and star used once */
        char *used = s->used.p;
        memset(used, 0, nn);
        char dused[MAXDET] = {0};
        qsort(pairs, np_, sizeof(Pair), pair_cmp);
        Py_ssize_t kept = 0;
        for (Py_ssize_t i = 0; i < np_; i++) {
            if (dused[pairs[i].d] || used[pairs[i].c])
                continue;
            dused[pairs[i].d] = used[pairs[i].c] = 1;
            pairs[kept++] = pairs[i];
        }
        np_ = kept;
    }
    for (Py_ssize_t i = 1; i < np_; i++) { /* by detection (each one once) */
        Pair x = pairs[i];
        Py_ssize_t j = i;
        while (j > 0 && pairs[j - 1].d > x.d) {
            pairs[j] = pairs[j - 1];
            j--;
        }
        pairs[j] = x;
    }
    for (Py_ssize_t i = 0; i < np_; i++) {
        det_m[i] = pairs[i].d;
        cat_m[i] = near[pairs[i].c];
    }
    *m = (int)np_;
    return 0;
}

static PyObject *KWNAMES; /* ("n_hypothesis", "p_single") */

/* How a hypothesis is fitted: a known field (fov, scale 1) or the scale fitted within a range. */
typedef struct {
    double fov, scale, scale_min, scale_max;
    int fit_scale;
} Fit;

/* verification -------------------------------------------------------------------------- */

typedef struct {
    double R[9], scale;
    int m;
    int64_t det[MAXDET], cat[MAXDET];
    double resid[MAXDET];
    double p_false;
} Verified;

static double median(const double *x, int m, double *work)
{
    memcpy(work, x, m * sizeof(double));
    for (int i = 1; i < m; i++) {
        double v = work[i];
        int j = i;
        while (j > 0 && work[j - 1] > v) {
            work[j] = work[j - 1];
            j--;
        }
        work[j] = v;
    }
    return m % 2 ? work[m / 2] : (work[m / 2 - 1] + work[m / 2]) / 2.0;
}

static int same_pairs(const Verified *o, const int64_t *det, const int64_t *cat, int m)
{
    return o->m == m && memcmp(o->det, det, m * sizeof(int64_t)) == 0 &&
           memcmp(o->cat, cat, m * sizeof(int64_t)) == 0;
}

/* The neighbourhood of a detection whose catalogue stars give its chance of a false match, in
 * initial match radii (verify.LOCAL_RADII). */
#define LOCAL_RADII 5.0

/* Mean chance of a match of the detections outside the hypothesis hyp, each at the catalogue
 * density within `wide` of it (its own pair o->det/o->cat left out), among the stars within
 * cone_rad of the boresight R[6..8]: Verifier._local_p. */
static double local_p(const Tables *t, const Scratch *s, const Frame *f, const double R[9],
                      double cone_rad, double radius, double wide, const int64_t hyp[K],
                      const Verified *o)
{
    const double *centre = R + 6, *vs = f->vs;
    const double cosc = cos(fmin(cone_rad, M_PI / 2.0));
    const double limit = 2.0 * sin(wide / 2.0), lim2 = limit * limit;
    const double reach = limit * (1.0 + 1e-9) + 1e-12; /* |dx| <= chord: a window in x */
    const int64_t *sky = s->sky.p;
    int count[MAXDET] = {0}, any = 0;
    for (size_t j = 0; j < s->sky.n; j++) {
        const double *st = t->stars + 3 * sky[j];
        if (!(dot3(st, centre) >= cosc))
            continue;
        any = 1;
        double c[3];
        for (int i = 0; i < 3; i++)
            c[i] = R[3 * i] * st[0] + R[3 * i + 1] * st[1] + R[3 * i + 2] * st[2];
        int lo = 0, hi = f->n; /* first detection with x >= c[0] - reach */
        while (lo < hi) {
            int mid = (lo + hi) / 2;
            if (f->xs[mid] < c[0] - reach)
                lo = mid + 1;
            else
                hi = mid;
        }
        for (int i = lo; i < f->n && f->xs[i] <= c[0] + reach; i++) {
            int d = f->xi[i];
            if (2.0 - 2.0 * dot3(vs + 3 * d, c) <= lim2)
                count[d]++;
        }
    }
    if (!any)
        return 0.0;
    for (int i = 0; i < o->m; i++) { /* the detection's own pair is not its neighbourhood */
        const double *st = t->stars + 3 * o->cat[i], *v = vs + 3 * o->det[i];
        double ss = 0.0;
        for (int a = 0; a < 3; a++) {
            double e = R[3 * a] * st[0] + R[3 * a + 1] * st[1] + R[3 * a + 2] * st[2] - v[a];
            ss += e * e;
        }
        if (sqrt(ss) <= limit)
            count[o->det[i]]--;
    }
    char in_hyp[MAXDET] = {0};
    for (int k = 0; k < K; k++)
        in_hyp[hyp[k]] = 1;
    const double per = M_PI * (radius * radius) / (2.0 * M_PI * (1.0 - cos(wide)));
    double sum = 0.0;
    int others = 0;
    for (int d = 0; d < f->n; d++) {
        if (in_hyp[d])
            continue;
        sum += fmin((double)count[d] * per, 1.0);
        others++;
    }
    return others ? sum / others : 0.0;
}

/* Verify the hypothesis det[i] = star cat[i] (K pairs) as Verifier.__call__ does: a known field
 * (how->fov, scale 1) or the scale fitted (how->fit_scale, from how->scale within its range).
 * Returns 1 accepted (out filled), 0 rejected, -1 error. */
static int verify(const Tables *t, Scratch *s, Frame *f, const Fit *how, const int64_t det[K],
                  const int64_t cat[K], PyObject *accept, double *best, Verified *out)
{
    const int n = f->n;
    int64_t det_m[MAXDET], cat_m[MAXDET];
    double work[MAXDET], p_single = 0.0, scale = how->scale;
    int m;
    memcpy(out->det, det, K * sizeof(int64_t));
    memcpy(out->cat, cat, K * sizeof(int64_t));
    out->m = K;
    if (how->fit_scale) {
        fit_scaled(t, f->tan, out->det, out->cat, K, &scale, out->R, out->resid);
        if (!(how->scale_min <= scale && scale <= how->scale_max))
            return 0;
        scaled_vectors(f->tan, n, scale, f->scaled);
        frame_init(f, f->scaled, n);
    } else {
        fit(t, f->vs, out->det, out->cat, K, out->R, out->resid);
    }
    const double max_off = f->max_off;
    double width = how->fit_scale ? 2.0 * max_off : how->fov;
    double radius = t->match_radius * width, rmax = 0.0;
    for (int k = 0; k < K; k++)
        rmax = fmax(rmax, out->resid[k]);
    if (rmax > radius)
        return 0;
    /* the catalogue stars of the field, once: later attitudes differ from this one by less
     * than the match radius */
    if (fetch_sky(t, s, out->R + 6, max_off + 4.0 * radius) < 0)
        return -1;
    for (int pass = 0; pass < 4; pass++) {
        if (pass >= 2) { /* the radius from the residuals of the last fit */
            double sig = median(out->resid, out->m, work) / sqrt(2.0 * log(2.0));
            if (pass == 2 && !how->fit_scale && 4.0 * sig >= radius)
                return 0; /* known optics, residuals filling the radius: not a rigid rotation */
            radius = fmin(radius, fmax(4.0 * sig, radius / 20.0));
        }
        if (match(t, s, f, out->R, max_off + radius, radius, det_m, cat_m, &m, &p_single) < 0)
            return -1;
        if (m < K)
            return 0;
        if (how->fit_scale || !same_pairs(out, det_m, cat_m, m)) {
            memcpy(out->det, det_m, m * sizeof(int64_t));
            memcpy(out->cat, cat_m, m * sizeof(int64_t));
            out->m = m;
            if (how->fit_scale)
                fit_scaled(t, f->tan, out->det, out->cat, m, &scale, out->R, out->resid);
            else
                fit(t, f->vs, out->det, out->cat, m, out->R, out->resid);
        }
        /* the first two passes check the scale (the last two do not, as Verifier) */
        if (pass < 2 && !(how->scale_min <= scale && scale <= how->scale_max))
            return 0;
        if (how->fit_scale) {
            scaled_vectors(f->tan, n, scale, f->scaled);
            double keep = f->max_off; /* the field's extent stays the first fit's */
            frame_init(f, f->scaled, n);
            f->max_off = keep;
        }
    }
    out->scale = scale;
    /* a cluster's detections land on its stars by chance more often than the mean says */
    double p_local = local_p(t, s, f, out->R, max_off + radius, radius,
                             LOCAL_RADII * t->match_radius * width, det, out);
    if (p_local > p_single)
        p_single = p_local;
    /* the decision: accept(n, m, n_hypothesis=K, p_single=p) -> (p_false, accepted) */
    PyObject *argv[4] = {PyLong_FromLong(n), PyLong_FromLong(m), PyLong_FromLong(K),
                         PyFloat_FromDouble(p_single)};
    PyObject *res = NULL;
    if (argv[0] && argv[1] && argv[2] && argv[3])
        res = PyObject_Vectorcall(accept, argv, 2, KWNAMES);
    for (int i = 0; i < 4; i++)
        Py_XDECREF(argv[i]);
    if (res == NULL)
        return -1;
    double p_false;
    int ok;
    if (!PyArg_ParseTuple(res, "dp", &p_false, &ok)) {
        Py_DECREF(res);
        return -1;
    }
    Py_DECREF(res);
    if (p_false < *best)
        *best = p_false;
    out->p_false = p_false;
    return ok ? 1 : 0;
}

/* the frame ----------------------------------------------------------------------------- */

static double now_s(void)
{
    struct timespec ts;
#ifdef CLOCK_MONOTONIC
    clock_gettime(CLOCK_MONOTONIC, &ts);
#else
    timespec_get(&ts, TIME_UTC);
#endif
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void scratch_free(Scratch *s)
{
    vec_free(&s->sky);
    vec_free(&s->near);
    vec_free(&s->cam);
    vec_free(&s->pairs);
    vec_free(&s->used);
}

static void scratch_init(Scratch *s)
{
    memset(s, 0, sizeof(*s));
    s->sky.item = sizeof(int64_t);
    s->near.item = sizeof(int64_t);
    s->cam.item = 3 * sizeof(double);
    s->pairs.item = sizeof(Pair);
    s->used.item = 1;
}

static Tables *get_tables(PyObject *capsule)
{
    return PyCapsule_GetPointer(capsule, "starsense.identify._hashc.Tables");
}

static int get_vectors(Py_buffer *b, PyObject *obj, Py_ssize_t *n)
{
    if (PyObject_GetBuffer(obj, b, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
        return -1;
    const char *f = b->format;
    while (*f == '@' || *f == '=' || *f == '<')
        f++;
    if (b->itemsize != 8 || strcmp(f, "d") != 0 || b->len % 24 != 0) {
        PyErr_SetString(PyExc_ValueError, "_hashc: vectors must be a C-contiguous (N, 3) float64");
        PyBuffer_Release(b);
        return -1;
    }
    *n = b->len / 24;
    return 0;
}

/* a bytearray: NumPy arrays on it (np.frombuffer) are writable, as the NumPy form's results */
static PyObject *bytes_of(const void *p, Py_ssize_t n) { return PyByteArray_FromStringAndSize(p, n); }

/* Verify the candidates of one pattern (det, its largest edge), nearest first: with a known
 * field those of the same size within scale_tol, at most max_cand of them. Returns 1 when one is
 * accepted (out filled), 0 when none is, -1 on error; counts them into *verified. */
static int try_candidates(const Tables *t, Scratch *s, Frame *frame, Fit *how,
                          const int64_t det[K], double largest, const Vec *cands,
                          PyObject *accept, double *best, Verified *out, long *verified)
{
    const Cand *cd = cands->p;
    int kept = 0;
    for (size_t i = 0; i < cands->n && kept < t->max_cand; i++) {
        double scale = (double)t->largest[cd[i].index] / largest;
        if (!how->fit_scale && !(fabs(scale - 1.0) <= t->scale_tol))
            continue;
        how->scale = how->fit_scale ? scale : 1.0;
        kept++;
        (*verified)++;
        int64_t cat[K];
        const int32_t *pt = t->patterns + K * cd[i].index;
        for (int k = 0; k < K; k++)
            cat[k] = pt[k];
        int rc = verify(t, s, frame, how, det, cat, accept, best, out);
        if (rc != 0)
            return rc;
    }
    return 0;
}

/* identify(tables, vectors, n_pattern, fov, accept, budget_s[, scale_min, scale_max,
 *          max_patterns]) ->
 *   (status, tried, verified, best, R bytes (9 float64) or None, det bytes, cat bytes, rms,
 *    p_false, scale)
 * status: 0 no match, 1 solved, 2 timeout (budget_s spent, or max_patterns looked up: the next
 * pattern is not; max_patterns < 0: no bound). fov <= 0: the field is unknown, the scale of
 * the tangent plane is fitted within [scale_min, scale_max] (HashIdentifier, fov_rad=None). */
static PyObject *py_identify(PyObject *self, PyObject *args)
{
    PyObject *cap, *vobj, *accept;
    int n_pattern;
    double fov, budget, scale_min = 0.0, scale_max = INFINITY;
    long max_patterns = -1;
    if (!PyArg_ParseTuple(args, "OOidOd|ddl", &cap, &vobj, &n_pattern, &fov, &accept, &budget,
                          &scale_min, &scale_max, &max_patterns))
        return NULL;
    int known = fov > 0.0;
    Tables *t = get_tables(cap);
    if (t == NULL)
        return NULL;
    Py_buffer vb;
    Py_ssize_t nv;
    if (get_vectors(&vb, vobj, &nv) < 0)
        return NULL;
    const double *v = vb.buf;
    int n = (int)(nv < t->max_det ? nv : t->max_det);
    int n_pat = (int)(nv < n_pattern ? nv : n_pattern);
    if (n_pat > n)
        n_pat = n; /* patterns draw on the verified detections only */
    Frame *frame = malloc(sizeof(Frame));
    if (frame == NULL) {
        PyBuffer_Release(&vb);
        return PyErr_NoMemory();
    }
    frame_init(frame, v, n);
    for (int i = 0; i < n; i++) { /* vectors_to_tangent */
        frame->tan[2 * i] = v[3 * i] / v[3 * i + 2];
        frame->tan[2 * i + 1] = v[3 * i + 1] / v[3 * i + 2];
    }
    Fit how = {known ? fov : 0.0, 1.0, known ? 0.0 : scale_min, known ? INFINITY : scale_max,
               !known};
    double t0 = budget < INFINITY ? now_s() : 0.0;
    Vec cands = {NULL, 0, 0, sizeof(Cand)};
    Scratch s;
    scratch_init(&s);
    Verified *out = malloc(sizeof(Verified));
    PyObject *ret = NULL;
    if (out == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    long tried = 0, verified = 0;
    double best = 1.0;
    int status = 0, rc = 0;
    for (int d = 3; d < n_pat && !status; d++)
        for (int a = 0; a < d && !status; a++)
            for (int b = a + 1; b < d && !status; b++)
                for (int c = b + 1; c < d && !status; c++) {
                    int64_t idx[K] = {a, b, c, d}, det[K];
                    double r[NR], largest;
                    if (!describe(v, idx, det, r, &largest))
                        continue;
                    if ((budget < INFINITY && now_s() - t0 > budget) ||
                        (max_patterns >= 0 && tried >= max_patterns)) {
                        status = 2;
                        break;
                    }
                    tried++;
                    if (lookup(t, r, &cands) < 0)
                        goto done;
                    rc = try_candidates(t, &s, frame, &how, det, largest, &cands, accept, &best,
                                        out, &verified);
                    if (rc < 0)
                        goto done;
                    if (rc == 1)
                        status = 1;
                }
    if (status == 1) {
        double ss = 0.0;
        for (int k = 0; k < out->m; k++)
            ss += out->resid[k] * out->resid[k];
        const double *R = out->R;
        ret = Py_BuildValue("(illdNNNddd)", 1, tried, verified, best,
                            bytes_of(R, 9 * sizeof(double)),
                            bytes_of(out->det, out->m * sizeof(int64_t)),
                            bytes_of(out->cat, out->m * sizeof(int64_t)), sqrt(ss / out->m),
                            out->p_false, out->scale);
    } else {
        ret = Py_BuildValue("(illdOOOddd)", status, tried, verified, best, Py_None, Py_None,
                            Py_None, NAN, 1.0, 1.0);
    }
done:
    free(out);
    free(frame);
    free(cands.p);
    scratch_free(&s);
    PyBuffer_Release(&vb);
    return ret;
}

/* describe(vectors, n_pattern) -> (count, det bytes (int64 x4), ratios bytes, largest bytes):
 * the described patterns of the first n_pattern detections, breadth first. */
static PyObject *py_describe(PyObject *self, PyObject *args)
{
    PyObject *vobj;
    int n_pattern;
    if (!PyArg_ParseTuple(args, "Oi", &vobj, &n_pattern))
        return NULL;
    Py_buffer vb;
    Py_ssize_t nv;
    if (get_vectors(&vb, vobj, &nv) < 0)
        return NULL;
    int n_pat = (int)(nv < n_pattern ? nv : n_pattern);
    Py_ssize_t most = n_pat < 4 ? 0 : (Py_ssize_t)n_pat * (n_pat - 1) * (n_pat - 2) * (n_pat - 3) / 24;
    int64_t *dets = malloc((most + 1) * K * sizeof(int64_t));
    double *ratios = malloc((most + 1) * NR * sizeof(double));
    double *largest = malloc((most + 1) * sizeof(double));
    PyObject *ret = NULL;
    if (!dets || !ratios || !largest) {
        PyErr_NoMemory();
        goto done;
    }
    Py_ssize_t count = 0;
    for (int d = 3; d < n_pat; d++)
        for (int a = 0; a < d; a++)
            for (int b = a + 1; b < d; b++)
                for (int c = b + 1; c < d; c++) {
                    int64_t idx[K] = {a, b, c, d};
                    if (describe(vb.buf, idx, dets + K * count, ratios + NR * count,
                                 largest + count))
                        count++;
                }
    ret = Py_BuildValue("(nNNN)", count, bytes_of(dets, count * K * sizeof(int64_t)),
                        bytes_of(ratios, count * NR * sizeof(double)),
                        bytes_of(largest, count * sizeof(double)));
done:
    free(dets);
    free(ratios);
    free(largest);
    PyBuffer_Release(&vb);
    return ret;
}

/* lookup(tables, r0, r1, r2, r3, r4) -> bytes (int64 candidate patterns, nearest first) */
static PyObject *py_lookup(PyObject *self, PyObject *args)
{
    PyObject *cap;
    double r[NR];
    if (!PyArg_ParseTuple(args, "Oddddd", &cap, r, r + 1, r + 2, r + 3, r + 4))
        return NULL;
    Tables *t = get_tables(cap);
    if (t == NULL)
        return NULL;
    Vec cands = {NULL, 0, 0, sizeof(Cand)};
    if (lookup(t, r, &cands) < 0) {
        free(cands.p);
        return NULL;
    }
    PyObject *out = PyBytes_FromStringAndSize(NULL, cands.n * sizeof(int64_t));
    if (out != NULL) {
        int64_t *o = (int64_t *)PyBytes_AS_STRING(out);
        for (size_t i = 0; i < cands.n; i++)
            o[i] = ((Cand *)cands.p)[i].index;
    }
    free(cands.p);
    return out;
}

/* verify(tables, vectors, det (4 ints), cat (4 ints), fov, accept[, scale, scale_min,
 *        scale_max]) -> None or (R 9-tuple, det bytes, cat bytes, rms, p_false, scale)
 * fov <= 0: the field is unknown, the scale fitted from `scale` within the range. */
static PyObject *py_verify(PyObject *self, PyObject *args)
{
    PyObject *cap, *vobj, *accept;
    int64_t det[K], cat[K];
    double fov, scale = 1.0, scale_min = 0.0, scale_max = INFINITY;
    if (!PyArg_ParseTuple(args, "OO(LLLL)(LLLL)dO|ddd", &cap, &vobj, det, det + 1, det + 2, det + 3,
                          cat, cat + 1, cat + 2, cat + 3, &fov, &accept, &scale, &scale_min,
                          &scale_max))
        return NULL;
    int known = fov > 0.0;
    Fit how = {known ? fov : 0.0, known ? 1.0 : scale, known ? 0.0 : scale_min,
               known ? INFINITY : scale_max, !known};
    Tables *t = get_tables(cap);
    if (t == NULL)
        return NULL;
    Py_buffer vb;
    Py_ssize_t nv;
    if (get_vectors(&vb, vobj, &nv) < 0)
        return NULL;
    const double *v = vb.buf;
    int n = (int)(nv < t->max_det ? nv : t->max_det);
    for (int k = 0; k < K; k++)
        if (det[k] < 0 || det[k] >= n || cat[k] < 0 || cat[k] >= t->n_stars) {
            PyBuffer_Release(&vb);
            PyErr_SetString(PyExc_IndexError, "_hashc.verify: a hypothesis index is out of range");
            return NULL;
        }
    double best = 1.0;
    Scratch s;
    scratch_init(&s);
    Verified *out = malloc(sizeof(Verified));
    Frame *frame = malloc(sizeof(Frame));
    PyObject *ret = NULL;
    if (out == NULL || frame == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    frame_init(frame, v, n);
    for (int i = 0; i < n; i++) {
        frame->tan[2 * i] = v[3 * i] / v[3 * i + 2];
        frame->tan[2 * i + 1] = v[3 * i + 1] / v[3 * i + 2];
    }
    int rc = verify(t, &s, frame, &how, det, cat, accept, &best, out);
    if (rc == 0) {
        Py_INCREF(Py_None);
        ret = Py_None;
    } else if (rc == 1) {
        double ss = 0.0;
        for (int k = 0; k < out->m; k++)
            ss += out->resid[k] * out->resid[k];
        const double *R = out->R;
        ret = Py_BuildValue("((ddddddddd)NNddd)", R[0], R[1], R[2], R[3], R[4], R[5], R[6],
                            R[7], R[8], bytes_of(out->det, out->m * sizeof(int64_t)),
                            bytes_of(out->cat, out->m * sizeof(int64_t)), sqrt(ss / out->m),
                            out->p_false, out->scale);
    }
done:
    free(out);
    free(frame);
    scratch_free(&s);
    PyBuffer_Release(&vb);
    return ret;
}

/* unit_vectors(v, out) -> bool: out = v / |v| row by row, as result.validate_vectors computes it
 * ((x0 x0 + x1 x1) + x2 x2, then a square root and a division); False (out undefined) if a row is
 * not finite, is zero or points behind the camera (z <= 0): the caller then raises its error. */
static PyObject *py_unit_vectors(PyObject *self, PyObject *args)
{
    PyObject *vobj, *oobj;
    if (!PyArg_ParseTuple(args, "OO", &vobj, &oobj))
        return NULL;
    Py_buffer vb, ob;
    Py_ssize_t nv, no;
    if (get_vectors(&vb, vobj, &nv) < 0)
        return NULL;
    if (PyObject_GetBuffer(oobj, &ob, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0) {
        PyBuffer_Release(&vb);
        return NULL;
    }
    no = ob.len / 24;
    int ok = ob.itemsize == 8 && ob.len == vb.len && no == nv;
    const double *v = vb.buf;
    double *o = ob.buf;
    for (Py_ssize_t i = 0; ok && i < nv; i++) {
        const double *x = v + 3 * i;
        ok = isfinite(x[0]) && isfinite(x[1]) && isfinite(x[2]);
        double norm = sqrt((x[0] * x[0] + x[1] * x[1]) + x[2] * x[2]);
        ok = ok && norm != 0.0;
        for (int j = 0; j < 3; j++)
            o[3 * i + j] = x[j] / norm;
        ok = ok && o[3 * i + 2] > 0.0;
    }
    PyBuffer_Release(&ob);
    PyBuffer_Release(&vb);
    return PyBool_FromLong(ok);
}

/* pinhole(x, y, cx, cy, f_px, out) -> bool: out[i] = the unit vector of ((x - cx) / f_px,
 * (y - cy) / f_px, 1), as solve.pinhole.pinhole_vectors computes it in NumPy (the same operations
 * in the same order: bit for bit); False (out undefined) if an x or y is not finite: the caller
 * then raises its error. x, y: C-contiguous float64 of one length; out: (N, 3) float64. */
static PyObject *py_pinhole(PyObject *self, PyObject *args)
{
    PyObject *xobj, *yobj, *oobj;
    double cx, cy, f;
    if (!PyArg_ParseTuple(args, "OOdddO", &xobj, &yobj, &cx, &cy, &f, &oobj))
        return NULL;
    Py_buffer b[3];
    PyObject *objs[3] = {xobj, yobj, oobj};
    int got = 0, ok = 1;
    for (; got < 3; got++) {
        int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (got == 2 ? PyBUF_WRITABLE : 0);
        if (PyObject_GetBuffer(objs[got], &b[got], flags) < 0)
            break;
        const char *fmt = b[got].format;
        while (*fmt == '@' || *fmt == '=' || *fmt == '<')
            fmt++;
        ok = ok && b[got].itemsize == 8 && strcmp(fmt, "d") == 0;
    }
    if (got < 3) {
        for (int i = 0; i < got; i++)
            PyBuffer_Release(&b[i]);
        return NULL;
    }
    Py_ssize_t n = b[0].len / 8;
    if (!ok || b[1].len != b[0].len || b[2].len != 3 * b[0].len) {
        for (int i = 0; i < 3; i++)
            PyBuffer_Release(&b[i]);
        PyErr_SetString(PyExc_ValueError, "_hashc.pinhole: x, y (N,) and out (N, 3) float64");
        return NULL;
    }
    const double *x = b[0].buf, *y = b[1].buf;
    double *o = b[2].buf;
    for (Py_ssize_t i = 0; i < n; i++) {
        ok = ok && isfinite(x[i]) && isfinite(y[i]);
        double u = (x[i] - cx) / f, w = (y[i] - cy) / f;
        double norm = sqrt((u * u + w * w) + 1.0 * 1.0);
        o[3 * i] = u / norm;
        o[3 * i + 1] = w / norm;
        o[3 * i + 2] = 1.0 / norm;
    }
    for (int i = 0; i < 3; i++)
        PyBuffer_Release(&b[i]);
    return PyBool_FromLong(ok);
}

/* the tables ---------------------------------------------------------------------------- */

static void tables_free(PyObject *capsule)
{
    Tables *t = get_tables(capsule);
    if (t == NULL)
        return;
    for (int i = 0; i < NBUF; i++)
        if (t->buf[i].obj != NULL)
            PyBuffer_Release(&t->buf[i]);
    free(t);
}

/* tables(keys, ratios, largest, patterns, stars, cell_start, cell_stars, cell_vectors, dir,
 *        dir_step, grid, cell, n_bins, max_error, scale_tol, match_radius, max_cand, max_det)
 * -> capsule. keys int64 (P,), ratios float32 (P, 5), largest float32 (P,), patterns int32
 * (P, 4), stars float64 (M, 3), cell_start int64 (grid^3 + 1,), cell_stars int64 (M,),
 * cell_vectors float64 (M, 3) = stars[cell_stars], dir int64 (D + 1,) with dir[b] the first
 * key >= b * dir_step (dir[D] = P, every key below D * dir_step): all C-contiguous. */
static PyObject *py_tables(PyObject *self, PyObject *args)
{
    PyObject *obj[NBUF];
    Tables *t = calloc(1, sizeof(Tables));
    if (t == NULL)
        return PyErr_NoMemory();
    if (!PyArg_ParseTuple(args, "OOOOOOOOOLididddii", &obj[0], &obj[1], &obj[2], &obj[3],
                          &obj[4], &obj[5], &obj[6], &obj[7], &obj[8], &t->dir_step, &t->grid, &t->cell, &t->n_bins,
                          &t->max_error, &t->scale_tol, &t->match_radius, &t->max_cand,
                          &t->max_det)) {
        free(t);
        return NULL;
    }
    static const char *fmt[NBUF] = {"l", "f", "f", "i", "d", "l", "l", "d", "l"};
    static const Py_ssize_t size[NBUF] = {8, 4, 4, 4, 8, 8, 8, 8, 8};
    for (int i = 0; i < NBUF; i++) {
        if (PyObject_GetBuffer(obj[i], &t->buf[i], PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
            goto fail;
        const char *f = t->buf[i].format;
        while (*f == '@' || *f == '=' || *f == '<')
            f++;
        if (t->buf[i].itemsize != size[i] ||
            (strcmp(f, fmt[i]) != 0 && !(fmt[i][0] == 'l' && strcmp(f, "q") == 0))) {
            PyErr_Format(PyExc_ValueError, "_hashc.tables: argument %d has format %s", i, f);
            goto fail;
        }
    }
    t->keys = t->buf[B_KEYS].buf;
    t->ratios = t->buf[B_RATIOS].buf;
    t->largest = t->buf[B_LARGEST].buf;
    t->patterns = t->buf[B_PATTERNS].buf;
    t->stars = t->buf[B_STARS].buf;
    t->cell_start = t->buf[B_CSTART].buf;
    t->cell_stars = t->buf[B_CSTARS].buf;
    t->cell_vectors = t->buf[B_CVEC].buf;
    t->dir = t->buf[B_DIR].buf;
    t->n_dir = t->buf[B_DIR].len / 8 - 1;
    t->n_patterns = t->buf[B_KEYS].len / 8;
    t->n_stars = t->buf[B_STARS].len / 24;
    if (t->buf[B_RATIOS].len != t->n_patterns * NR * 4 ||
        t->buf[B_LARGEST].len != t->n_patterns * 4 ||
        t->buf[B_PATTERNS].len != t->n_patterns * K * 4 || t->grid < 1 ||
        t->buf[B_CSTART].len != ((Py_ssize_t)t->grid * t->grid * t->grid + 1) * 8 ||
        t->buf[B_CSTARS].len != t->n_stars * 8 || t->buf[B_CVEC].len != t->n_stars * 24 ||
        t->n_dir < 1 || t->dir_step < 1 || t->dir[0] != 0 || t->dir[t->n_dir] != t->n_patterns ||
        t->max_det < K || t->max_det > MAXDET) {
        PyErr_SetString(PyExc_ValueError, "_hashc.tables: inconsistent array sizes");
        goto fail;
    }
    PyObject *cap = PyCapsule_New(t, "starsense.identify._hashc.Tables", tables_free);
    if (cap == NULL)
        goto fail;
    return cap;
fail:
    for (int i = 0; i < NBUF; i++)
        if (t->buf[i].obj != NULL)
            PyBuffer_Release(&t->buf[i]);
    free(t);
    return NULL;
}

static PyMethodDef methods[] = {
    {"tables", py_tables, METH_VARARGS, "Hold a database's arrays for identify (see _hashc.c)."},
    {"identify", py_identify, METH_VARARGS, "Identify one frame (see _hashc.c)."},
    {"describe", py_describe, METH_VARARGS, "Patterns of the brightest detections."},
    {"lookup", py_lookup, METH_VARARGS, "Candidate database patterns of edge ratios."},
    {"verify", py_verify, METH_VARARGS, "Verify one hypothesis."},
    {"unit_vectors", py_unit_vectors, METH_VARARGS, "Checked unit vectors of detections."},
    {"pinhole", py_pinhole, METH_VARARGS, "Unit vectors of pixel positions through a pinhole."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_hashc", NULL, -1, methods,
                                    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__hashc(void)
{
    if (KWNAMES == NULL && (KWNAMES = Py_BuildValue("(ss)", "n_hypothesis", "p_single")) == NULL)
        return NULL;
    return PyModule_Create(&module);
}
