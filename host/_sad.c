/*
 * The fast software correlator: the golden model's exact integers (lost.model.correlate), computed
 * with SIMD over output columns and OpenMP over output rows.
 *
 * Every placement's term is |a[i+k][j+l] - c[i][j] - q[k][l]| with, in mean-compensated mode,
 * a = n*M, c = window sum of M - sum of S, q = n*S (so the term is n*(M-S) - (sumM - sumS), the
 * definition), and in plain mode a = M, c = 0, q = S. The Python wrapper (lost.host.software) checks
 * the inputs and chooses `chunk`, the number of terms whose sum is known to fit 32 unsigned bits
 * (lost.model.widths), so the 32-bit lane arithmetic below is exact; partial sums go to int64.
 *
 * The hot loop keeps a block of output columns in registers (4 vectors) and streams the patch
 * nodes past it: one load, three ALU ops and one add per vector of terms.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define LOST_X86 1
#include <immintrin.h>
#endif

/* Widest block any kernel reads: the padding every row of `a` carries past its last column. */
#define BLOCK_MAX 64

/* Below this many terms (about 0.1 ms on one core) waking a thread team costs more than it saves:
 * the navigation pipeline correlates ~70 x 70 sub-maps at every record. */
#define PARALLEL_MIN_TERMS 4000000
#define ROWS_PER_BAND 8

typedef void (*block_kernel)(const int32_t *a, const int32_t *c, const int32_t *offs,
                             const int32_t *qs, int nt, uint32_t *acc, int cols);

/* Portable kernel: plain loops the compiler may vectorize at the baseline ISA. */
static void kernel_generic(const int32_t *a, const int32_t *c, const int32_t *offs,
                           const int32_t *qs, int nt, uint32_t *acc, int cols) {
    for (int j0 = 0; j0 < cols; j0 += 16) {
        uint32_t s[16] = {0};
        for (int t = 0; t < nt; t++) {
            const int32_t *r = a + offs[t] + j0;
            int32_t q = qs[t];
            for (int jj = 0; jj < 16; jj++) {
                int32_t x = r[jj] - c[j0 + jj] - q;
                s[jj] += (uint32_t)(x < 0 ? -x : x);
            }
        }
        memcpy(acc + j0, s, sizeof s);
    }
}

#ifdef LOST_X86
__attribute__((target("avx2"))) static void kernel_avx2(const int32_t *a, const int32_t *c,
                                                        const int32_t *offs, const int32_t *qs,
                                                        int nt, uint32_t *acc, int cols) {
    for (int j0 = 0; j0 < cols; j0 += 32) {
        __m256i s0 = _mm256_setzero_si256(), s1 = s0, s2 = s0, s3 = s0;
        const __m256i c0 = _mm256_loadu_si256((const __m256i *)(c + j0));
        const __m256i c1 = _mm256_loadu_si256((const __m256i *)(c + j0 + 8));
        const __m256i c2 = _mm256_loadu_si256((const __m256i *)(c + j0 + 16));
        const __m256i c3 = _mm256_loadu_si256((const __m256i *)(c + j0 + 24));
        for (int t = 0; t < nt; t++) {
            const int32_t *r = a + offs[t] + j0;
            const __m256i q = _mm256_set1_epi32(qs[t]);
#define LOST_TERM256(s, cc, o) \
    s = _mm256_add_epi32(s, _mm256_abs_epi32(_mm256_sub_epi32( \
            _mm256_loadu_si256((const __m256i *)(r + o)), _mm256_add_epi32(cc, q))))
            LOST_TERM256(s0, c0, 0);
            LOST_TERM256(s1, c1, 8);
            LOST_TERM256(s2, c2, 16);
            LOST_TERM256(s3, c3, 24);
#undef LOST_TERM256
        }
        _mm256_storeu_si256((__m256i *)(acc + j0), s0);
        _mm256_storeu_si256((__m256i *)(acc + j0 + 8), s1);
        _mm256_storeu_si256((__m256i *)(acc + j0 + 16), s2);
        _mm256_storeu_si256((__m256i *)(acc + j0 + 24), s3);
    }
}

__attribute__((target("avx512f"))) static void kernel_avx512(const int32_t *a, const int32_t *c,
                                                             const int32_t *offs, const int32_t *qs,
                                                             int nt, uint32_t *acc, int cols) {
    for (int j0 = 0; j0 < cols; j0 += 64) {
        __m512i s0 = _mm512_setzero_si512(), s1 = s0, s2 = s0, s3 = s0;
        const __m512i c0 = _mm512_loadu_si512(c + j0);
        const __m512i c1 = _mm512_loadu_si512(c + j0 + 16);
        const __m512i c2 = _mm512_loadu_si512(c + j0 + 32);
        const __m512i c3 = _mm512_loadu_si512(c + j0 + 48);
        for (int t = 0; t < nt; t++) {
            const int32_t *r = a + offs[t] + j0;
            const __m512i q = _mm512_set1_epi32(qs[t]);
#define LOST_TERM512(s, cc, o) \
    s = _mm512_add_epi32(s, _mm512_abs_epi32(_mm512_sub_epi32(_mm512_loadu_si512(r + o), \
                                                              _mm512_add_epi32(cc, q))))
            LOST_TERM512(s0, c0, 0);
            LOST_TERM512(s1, c1, 16);
            LOST_TERM512(s2, c2, 32);
            LOST_TERM512(s3, c3, 48);
#undef LOST_TERM512
        }
        _mm512_storeu_si512(acc + j0, s0);
        _mm512_storeu_si512(acc + j0 + 16, s1);
        _mm512_storeu_si512(acc + j0 + 32, s2);
        _mm512_storeu_si512(acc + j0 + 48, s3);
    }
}
#endif

static block_kernel choose_kernel(const char **name) {
#ifdef LOST_X86
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f")) { *name = "avx512"; return kernel_avx512; }
    if (__builtin_cpu_supports("avx2")) { *name = "avx2"; return kernel_avx2; }
#endif
    *name = "generic";
    return kernel_generic;
}

static block_kernel KERNEL;
static const char *KERNEL_NAME;

static int get_buffer(PyObject *obj, Py_buffer *view, const char *name, Py_ssize_t itemsize,
                      Py_ssize_t len, int writable) {
    int flags = PyBUF_C_CONTIGUOUS | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) return -1;
    if (view->itemsize != itemsize || view->len != len * itemsize) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd items of %zd bytes", name, len, itemsize);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

/*
 * surface(terrain: int16[H*W], patch: int16[h*w], mask: uint8[h*w], H, W, h, w,
 *         mean_compensation, chunk, out: int64[(H-h+1)*(W-w+1)]) -> None
 */
static PyObject *surface(PyObject *self, PyObject *args) {
    PyObject *terrain_obj, *patch_obj, *mask_obj, *out_obj;
    int H, W, h, w, mean_compensation, chunk;
    if (!PyArg_ParseTuple(args, "OOOiiiipiO", &terrain_obj, &patch_obj, &mask_obj, &H, &W, &h, &w,
                          &mean_compensation, &chunk, &out_obj))
        return NULL;
    if (H < 1 || W < 1 || h < 1 || w < 1 || h > H || w > W || chunk < 1) {
        PyErr_SetString(PyExc_ValueError, "surface: bad sizes or chunk");
        return NULL;
    }
    const int rows = H - h + 1, cols = W - w + 1;
    Py_buffer tb, pb, mb, ob;
    if (get_buffer(terrain_obj, &tb, "terrain", 2, (Py_ssize_t)H * W, 0) < 0) return NULL;
    if (get_buffer(patch_obj, &pb, "patch", 2, (Py_ssize_t)h * w, 0) < 0) goto fail_t;
    if (get_buffer(mask_obj, &mb, "mask", 1, (Py_ssize_t)h * w, 0) < 0) goto fail_p;
    if (get_buffer(out_obj, &ob, "out", 8, (Py_ssize_t)rows * cols, 1) < 0) goto fail_m;

    const int16_t *M = tb.buf, *S = pb.buf;
    const uint8_t *mask = mb.buf;
    int64_t *out = ob.buf;
    /* Rows of `a` carry BLOCK_MAX columns of padding so a block may read past the last column. */
    const int stride = W + BLOCK_MAX;
    const int cols_padded = (cols + BLOCK_MAX - 1) / BLOCK_MAX * BLOCK_MAX;
    int n = 0;
    int64_t patch_sum = 0;
    for (int k = 0; k < h * w; k++)
        if (mask[k]) { n++; patch_sum += S[k]; }
    int n_invalid = h * w - n;

    int32_t *offs = malloc(sizeof(int32_t) * (size_t)(n ? n : 1));
    int32_t *qs = malloc(sizeof(int32_t) * (size_t)(n ? n : 1));
    int32_t *invalid = malloc(sizeof(int32_t) * (size_t)(n_invalid ? n_invalid : 1));
    int32_t *a = calloc((size_t)H * stride, sizeof(int32_t));
    int ok = offs && qs && invalid && a && n > 0;
    if (!ok) {
        free(offs); free(qs); free(invalid); free(a);
        if (n == 0) PyErr_SetString(PyExc_ValueError, "surface: mask has no valid node");
        else PyErr_NoMemory();
        PyBuffer_Release(&ob); PyBuffer_Release(&mb); PyBuffer_Release(&pb); PyBuffer_Release(&tb);
        return NULL;
    }
    const int32_t scale = mean_compensation ? n : 1;
    for (int k = 0, t = 0, u = 0; k < h; k++)
        for (int l = 0; l < w; l++) {
            if (mask[k * w + l]) { offs[t] = k * stride + l; qs[t] = scale * S[k * w + l]; t++; }
            else { invalid[u++] = k * W + l; }
        }

    int failed = 0;
    Py_BEGIN_ALLOW_THREADS
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) a[(size_t)y * stride + x] = scale * M[(size_t)y * W + x];

    const int parallel = (int64_t)rows * cols * n >= PARALLEL_MIN_TERMS;
#pragma omp parallel if (parallel)
    {
        int32_t *colsum = calloc((size_t)W, sizeof(int32_t));
        int32_t *c = calloc((size_t)cols_padded, sizeof(int32_t));
        uint32_t *acc = calloc((size_t)cols_padded, sizeof(uint32_t));
        if (!colsum || !c || !acc) {
#pragma omp atomic write
            failed = 1;
        } else {
            /* Bands of rows handed out dynamically, so a thread the OS parks does not hold up the
             * call; within a band the column sums slide down one row at a time. */
#pragma omp for schedule(dynamic, 1)
            for (int band = 0; band < (rows + ROWS_PER_BAND - 1) / ROWS_PER_BAND; band++) {
                const int r0 = band * ROWS_PER_BAND;
                const int r1 = r0 + ROWS_PER_BAND < rows ? r0 + ROWS_PER_BAND : rows;
                for (int i = r0; i < r1; i++) {
                    if (mean_compensation) {
                        if (i == r0) {
                            for (int x = 0; x < W; x++) {
                                int32_t s = 0;
                                for (int k = 0; k < h; k++) s += M[(size_t)(i + k) * W + x];
                                colsum[x] = s;
                            }
                        } else {
                            for (int x = 0; x < W; x++)
                                colsum[x] += M[(size_t)(i + h - 1) * W + x] - M[(size_t)(i - 1) * W + x];
                        }
                        int32_t box = 0;
                        for (int l = 0; l < w; l++) box += colsum[l];
                        for (int j = 0; j < cols; j++) {
                            c[j] = box;
                            if (j + w < W) box += colsum[j + w] - colsum[j];
                        }
                        for (int u = 0; u < n_invalid; u++) {
                            const int16_t *r = M + (size_t)i * W + invalid[u];
                            for (int j = 0; j < cols; j++) c[j] -= r[j];
                        }
                        for (int j = 0; j < cols; j++) c[j] -= (int32_t)patch_sum;
                    }
                    int64_t *o = out + (size_t)i * cols;
                    const int32_t *arow = a + (size_t)i * stride;
                    for (int t0 = 0; t0 < n; t0 += chunk) {
                        int nt = n - t0 < chunk ? n - t0 : chunk;
                        KERNEL(arow, c, offs + t0, qs + t0, nt, acc, cols);
                        if (t0 == 0)
                            for (int j = 0; j < cols; j++) o[j] = acc[j];
                        else
                            for (int j = 0; j < cols; j++) o[j] += acc[j];
                    }
                }
            }
        }
        free(colsum); free(c); free(acc);
    }
    Py_END_ALLOW_THREADS

    free(offs); free(qs); free(invalid); free(a);
    PyBuffer_Release(&ob); PyBuffer_Release(&mb); PyBuffer_Release(&pb); PyBuffer_Release(&tb);
    if (failed) return PyErr_NoMemory();
    Py_RETURN_NONE;

fail_m:
    PyBuffer_Release(&mb);
fail_p:
    PyBuffer_Release(&pb);
fail_t:
    PyBuffer_Release(&tb);
    return NULL;
}

static PyMethodDef methods[] = {
    {"surface", surface, METH_VARARGS, "Exact correlation surface into a preallocated int64 array."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_sad", NULL, -1, methods};

PyMODINIT_FUNC PyInit__sad(void) {
    KERNEL = choose_kernel(&KERNEL_NAME);
    PyObject *m = PyModule_Create(&module);
    if (m == NULL) return NULL;
    if (PyModule_AddStringConstant(m, "KERNEL", KERNEL_NAME) < 0) { Py_DECREF(m); return NULL; }
#ifdef _OPENMP
    PyModule_AddIntConstant(m, "OPENMP", 1);
#else
    PyModule_AddIntConstant(m, "OPENMP", 0);
#endif
    return m;
}
