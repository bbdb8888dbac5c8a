/*
 * Body collisions, compiled: exact closest point, signed distance and push-out of points against a
 * triangle mesh whose vertices move every frame while its triangles stay the same (the posed body).
 *
 * Portable C99 with no dependencies (the C++ runtime compiles this file as is and the JavaScript runtime
 * ports it line for line): plain loops over plain arrays, float64 arithmetic, no SIMD, no threads (a
 * caller runs disjoint ranges of points on as many threads as it likes: every point is independent and
 * its result does not depend on the range, the thread or the order).  Compile without floating-point
 * contraction (-ffp-contract=off) so that every platform rounds the same.
 *
 * The rule is the one of segadeform.body.collision.BodyProxy / push_out (the slow, obvious references):
 *
 *   closest point  the exact nearest point over every triangle (Ericson, Real-Time Collision Detection,
 *                  5.1.5, with the reference's guards), ties broken by the lowest face index;
 *   sign           from the angle-weighted pseudo-normal (Baerentzen & Aanaes 2005) of the feature the
 *                  closest point lies on: the face (three barycentric weights > 1e-9), an edge (two: the
 *                  normalised sum of the normals of the faces sharing it) or a vertex (one: the normalised
 *                  sum of the face normals around it, each weighted by the face's angle at the vertex);
 *                  exact for a closed, consistently oriented mesh;
 *   buried         where the posed body intersects itself (an arm pressed into the torso) the closest surface of
 *                  a point inside the torso can be the arm's skin buried in it, whose side says outside.  A point
 *                  that the closest feature's side calls outside but the body's winding number (a ray's signed
 *                  crossings, below) calls inside (a point farther than SDC_BURY * scale from its closest
 *                  point: a nearer one is on the surface) takes instead the nearest point of the faces whose own
 *                  nearest point to it is not buried -- a surface point is buried when the point SDC_BURY * scale
 *                  out from it along its face's normal is inside the body -- with signed distance minus its
 *                  distance (a face's centroid instead left a quarter of such points inside after three passes on
 *                  the test's two pressed spheres, where faces straddle the crease): it is
 *                  pushed to the skin that is really outside, never onto the buried one (issue #26: a dress's
 *                  vertices in the torso next to a buried arm stayed there) -- but only to skin within SDC_PINCH *
 *                  scale: a point deeper in the crease stays pinched, as the simulator leaves such cloth (the nearest
 *                  open skin, 4-7 cm away there, was in front of the arm one frame and behind it the next: a
 *                  T-shirt's armpit vertices jumped up to 16 cm between frames of a walk).  A face of zero area is never taken;
 *                  at most SDC_BURY_TRIES faces are tested for one point (past that it keeps its closest surface);
 *                  a body that is not closed has no winding number and no such rule.  The push-out applies it to
 *                  every point; sdc_near to none for the cloth stage's contacts, to points farther than its
 *                  radius for its backstop's traces (near_or_inside);
 *   push-out       p' = closest + margin * n for points with signed distance < margin, again for the
 *                  points moved, up to `iterations` passes.
 *   carried        (sdc_push_out_carried, the runtimes' collision stage) the frames are consecutive and each point's
 *                  correction (after minus before) is carried from one to the next: where the closest exit jumps to
 *                  another side of a limb -- a point deep in it, whose nearest side flips with every small move --
 *                  the push-out from the point plus the frame before's correction (and half of it) is tried too and
 *                  the exit nearest that correction kept, within bounds (carry_point).
 *
 * How it is made cheap:
 *
 *   build (once per topology)  a binary bounding-volume hierarchy over the triangles, split at the median
 *       centroid along the longest axis, from one pose (only its tightness depends on that pose); each
 *       leaf's distinct vertices; the faces around every edge and every vertex; whether the mesh is closed
 *       (every edge has exactly two faces that run along it in opposite directions).
 *   refit (per frame)  the boxes bottom-up from the posed vertices (nodes are stored parents first).
 *       Normals are computed only for the feature a point's closest point lies on.
 *   near (per point)  branch and bound over the tree for the nearest triangle within a radius a little
 *       over the margin: if one is found, it is the exact closest point.
 *   far (per point)  nothing within the radius: the point is outside (untouched) unless it is inside.  A
 *       ray along a coordinate axis (the shortest way out of the root box) is traced through the tree
 *       and its crossings summed with their orientation: zero outside a closed mesh.  The 2-D edge
 *       functions are exactly antisymmetric between the two faces of an edge, so a ray through an edge
 *       counts once; a ray exactly through an edge or a vertex, or a mesh that is not closed, falls back
 *       to the exact unbounded query, as does every point found inside (its branch and bound starts from
 *       the distance to the ray's first hit).
 *
 * Determinism: a box is pruned only when it is farther than the best distance plus a slack above the
 * rounding error, so the global minimum of (squared distance, face index) is always examined: the result
 * is that minimum whatever the tree, the traversal order or the thread.
 */

#ifdef SDC_PYTHON_MODULE
#include <Python.h> /* first, as Python asks; only for the empty module at the end of the file */
#endif
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#if defined(_WIN32)
#define SDC_API __declspec(dllexport)
#else
#define SDC_API __attribute__((visibility("default")))
#endif

#define SDC_STACK 256 /* traversal stack; the median split keeps the depth under log2(F) + 1 */
#define SDC_TINY 1e-300
#define SDC_FEATURE 1e-9 /* a barycentric weight at or under this is zero (the reference's rule) */
#define SDC_BURY 1e-6    /* a surface point is buried if the point this far out along its face's normal (times the
                            * posed body's size: its bounding box's longest side) is inside the body */
#define SDC_BURY_TRIES 512 /* at most this many faces tested for one point (nearest_open) */
#define SDC_PINCH 0.012    /* a point in the body by its winding number but outside by its closest surface is taken to
                            * the nearest skin that is not buried only within this distance (times the posed body's
                            * size: 2.1 cm on a body 1.75 m tall); deeper in the crease it stays pinched */
#define SDC_CARRY_LIMB 1.5 /* the carried push-out (sdc_push_out_carried): another exit is taken only if its move is */
#define SDC_CARRY_GROW 0.25 /* at most SDC_CARRY_LIMB times the closest exit's plus SDC_PINCH * scale, and at most the
                             * frame before's plus SDC_CARRY_GROW * SDC_PINCH * scale */

typedef struct {
    int64_t nv, nf, n_nodes, depth;
    int64_t *faces;      /* (F, 3) */
    int64_t *left;       /* (n_nodes) first child; -1 for a leaf */
    int64_t *right;      /* (n_nodes) second child (left + 1); -1 for a leaf */
    int64_t *first;      /* (n_nodes) a leaf's first entry in leaf_face */
    int64_t *count;      /* (n_nodes) a leaf's number of faces */
    int64_t *leaf_face;  /* (F) faces in leaf order */
    int64_t *vptr;       /* (n_nodes + 1) a leaf's distinct vertices in leaf_vert[vptr[i]:vptr[i + 1]] */
    int64_t *leaf_vert;
    int64_t *edge_of;    /* (3F) the edge of each face slot (slot 3f + c: the edge opposite corner c) */
    int64_t *eptr;       /* (E + 1) the slots of edge e: eslot[eptr[e]:eptr[e + 1]], ascending */
    int64_t *eslot;
    int64_t *vfptr;      /* (V + 1) the corners at vertex v: vcorner[vfptr[v]:vfptr[v + 1]], ascending */
    int64_t *vcorner;
    int closed;
} sdc_body;

/* ---- small vector helpers ------------------------------------------------------------------------ */
static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void sub3(const double *a, const double *b, double *out) {
    out[0] = a[0] - b[0];
    out[1] = a[1] - b[1];
    out[2] = a[2] - b[2];
}

static void cross3(const double *a, const double *b, double *out) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

static double norm3(const double *a) { return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

static void normalize3(double *a) {
    double n = norm3(a);
    if (n < SDC_TINY) n = SDC_TINY;
    a[0] /= n;
    a[1] /= n;
    a[2] /= n;
}

/* acos(x), x in [-1, 1], from + - * / and sqrt alone (all correctly rounded in IEEE 754), so that this file and its
 * JavaScript port give the same bits: a C library's acos and JavaScript's Math.acos disagree in the last bit on
 * about 7 % of inputs (tests/runtimes/test_collisions.py reports it), and a push-out in a crease, carried from
 * frame to frame by the cloth stage, can turn one bit into centimetres.  asin(y) = y + y r(y^2) on |y| <= 1/2, r(z) = z P(z) / Q(z) the minimax rational of
 * fdlibm's e_asin.c (Sun Microsystems, 1993; the coefficients only); acos(x) = pi/2 - asin(x) for |x| <= 1/2 and
 * 2 asin(s) (x > 1/2) or pi - 2 asin(s) (x < -1/2) with s = sqrt((1 - |x|) / 2).  Within 1.2 ulp (5.2e-16 rad)
 * of acos over [-1, 1] (measured once against numpy's long double acos, glibc's being within 0.52;
 * tests/body/test_collision_compiled.py holds it to 2 ulp). */
static double sdc_asin_r(double z) {
    double p = z * (1.66666666666666657415e-01 +
                     z * (-3.25565818622400915405e-01 +
                          z * (2.01212532134862925881e-01 +
                               z * (-4.00555345006794114027e-02 +
                                    z * (7.91534994289814532176e-04 + z * 3.47933107596021167570e-05)))));
    double q = 1.0 + z * (-2.40339491173441421878e+00 +
                          z * (2.02094576023350569471e+00 +
                               z * (-6.88283971605453293030e-01 + z * 7.70381505559019352791e-02)));
    return p / q;
}

SDC_API double sdc_acos(double x) {
    double s;
    if (x != x) return x;
    if (x > 1) x = 1;
    if (x < -1) x = -1;
    if (x <= 0.5 && x >= -0.5) return 1.57079632679489655800e+00 - (x + x * sdc_asin_r(x * x));
    s = sqrt((1.0 - (x < 0 ? -x : x)) * 0.5);
    s = 2.0 * (s + s * sdc_asin_r(s * s));
    return x > 0 ? s : 3.14159265358979311600e+00 - s;
}

/* ---- build -------------------------------------------------------------------------------------- */
typedef struct {
    int64_t key, slot;
} sdc_pair;

static int cmp_pair(const void *x, const void *y) {
    const sdc_pair *a = (const sdc_pair *)x, *b = (const sdc_pair *)y;
    if (a->key != b->key) return a->key < b->key ? -1 : 1;
    return a->slot < b->slot ? -1 : (a->slot > b->slot ? 1 : 0);
}

/* Reorder idx[lo:hi] so that idx[mid] has the median key, smaller keys before it, larger after
 * (quickselect, ties broken by the face index so that the tree is the same on every platform). */
static int less_key(const double *key, int64_t a, int64_t b) {
    return key[a] < key[b] || (key[a] == key[b] && a < b);
}

static void select_median(int64_t *idx, const double *key, int64_t lo, int64_t hi, int64_t mid) {
    while (hi - lo > 1) {
        int64_t a = idx[lo], b = idx[lo + (hi - lo) / 2], c = idx[hi - 1], pivot, i, j, t;
        /* median of three as the pivot */
        if (less_key(key, b, a)) { t = a; a = b; b = t; }
        if (less_key(key, c, b)) { t = b; b = c; c = t; }
        if (less_key(key, b, a)) { t = a; a = b; b = t; }
        pivot = b;
        /* three-way-free Lomuto partition with the pivot moved to the end */
        for (i = lo; i < hi; i++)
            if (idx[i] == pivot) { idx[i] = idx[hi - 1]; idx[hi - 1] = pivot; break; }
        j = lo;
        for (i = lo; i < hi - 1; i++)
            if (less_key(key, idx[i], pivot)) { t = idx[i]; idx[i] = idx[j]; idx[j] = t; j++; }
        idx[hi - 1] = idx[j];
        idx[j] = pivot;
        if (j == mid) return;
        if (mid < j) hi = j; else lo = j + 1;
    }
}

typedef struct {
    int64_t lo, hi, node, depth;
} sdc_task;

static void free_body(sdc_body *b) {
    if (!b) return;
    free(b->faces); free(b->left); free(b->right); free(b->first); free(b->count); free(b->leaf_face);
    free(b->vptr); free(b->leaf_vert); free(b->edge_of); free(b->eptr); free(b->eslot); free(b->vfptr);
    free(b->vcorner);
    free(b);
}

/* The tree over the faces, from vertices (V, 3) of one pose: nodes in depth-first order (a parent before
 * its children), each leaf holding at most leaf_size faces.  Returns 0, or -1 when out of memory. */
static int build_tree(sdc_body *b, const double *verts, int64_t leaf_size) {
    int64_t nf = b->nf, cap = 2 * nf + 1, i, k, n = 0, top = 0, nvl = 0;
    double *cen = (double *)malloc(sizeof(double) * 3 * (size_t)nf);
    double *key = (double *)malloc(sizeof(double) * (size_t)nf);
    sdc_task *stack = (sdc_task *)malloc(sizeof(sdc_task) * (size_t)(cap + 1));
    int64_t *mark = NULL;
    int ok = cen && key && stack;
    b->left = (int64_t *)malloc(sizeof(int64_t) * (size_t)cap);
    b->right = (int64_t *)malloc(sizeof(int64_t) * (size_t)cap);
    b->first = (int64_t *)malloc(sizeof(int64_t) * (size_t)cap);
    b->count = (int64_t *)malloc(sizeof(int64_t) * (size_t)cap);
    b->leaf_face = (int64_t *)malloc(sizeof(int64_t) * (size_t)nf);
    ok = ok && b->left && b->right && b->first && b->count && b->leaf_face;
    if (!ok) { free(cen); free(key); free(stack); return -1; }
    for (i = 0; i < nf; i++) {
        const int64_t *f = b->faces + 3 * i;
        for (k = 0; k < 3; k++)
            cen[3 * i + k] = (verts[3 * f[0] + k] + verts[3 * f[1] + k] + verts[3 * f[2] + k]) / 3.0;
        b->leaf_face[i] = i;
    }
    /* depth first; the two children of a node get consecutive numbers (their boxes share cache lines),
     * after their parent's (the refit runs backwards) */
    b->depth = 0;
    stack[top].lo = 0; stack[top].hi = nf; stack[top].node = 0; stack[top].depth = 0;
    top++;
    n = 1;
    while (top > 0) {
        sdc_task t = stack[--top];
        int64_t node = t.node;
        if (t.depth > b->depth) b->depth = t.depth;
        b->first[node] = t.lo;
        b->count[node] = t.hi - t.lo;
        b->left[node] = b->right[node] = -1;
        if (t.hi - t.lo > leaf_size) {
            double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
            int axis = 0;
            int64_t mid = t.lo + (t.hi - t.lo) / 2;
            for (i = t.lo; i < t.hi; i++)
                for (k = 0; k < 3; k++) {
                    double c = cen[3 * b->leaf_face[i] + k];
                    if (c < lo[k]) lo[k] = c;
                    if (c > hi[k]) hi[k] = c;
                }
            if (hi[1] - lo[1] > hi[axis] - lo[axis]) axis = 1;
            if (hi[2] - lo[2] > hi[axis] - lo[axis]) axis = 2;
            for (i = t.lo; i < t.hi; i++) key[b->leaf_face[i]] = cen[3 * b->leaf_face[i] + axis];
            select_median(b->leaf_face, key, t.lo, t.hi, mid);
            b->count[node] = 0;
            b->left[node] = n;
            b->right[node] = n + 1;
            /* the right child is pushed first so that the left one's subtree is numbered next */
            stack[top].lo = mid; stack[top].hi = t.hi; stack[top].node = n + 1; stack[top].depth = t.depth + 1;
            top++;
            stack[top].lo = t.lo; stack[top].hi = mid; stack[top].node = n; stack[top].depth = t.depth + 1;
            top++;
            n += 2;
        }
    }
    b->n_nodes = n;
    free(cen); free(key); free(stack);
    /* each leaf's distinct vertices (for the refit) */
    b->vptr = (int64_t *)malloc(sizeof(int64_t) * (size_t)(n + 1));
    b->leaf_vert = (int64_t *)malloc(sizeof(int64_t) * 3 * (size_t)nf);
    mark = (int64_t *)malloc(sizeof(int64_t) * (size_t)b->nv);
    if (!b->vptr || !b->leaf_vert || !mark) { free(mark); return -1; }
    for (i = 0; i < b->nv; i++) mark[i] = -1;
    for (i = 0; i < n; i++) {
        b->vptr[i] = nvl;
        if (b->left[i] < 0) {
            int64_t j;
            for (j = b->first[i]; j < b->first[i] + b->count[i]; j++)
                for (k = 0; k < 3; k++) {
                    int64_t v = b->faces[3 * b->leaf_face[j] + k];
                    if (mark[v] != i) { mark[v] = i; b->leaf_vert[nvl++] = v; }
                }
        }
    }
    b->vptr[n] = nvl;
    free(mark);
    return 0;
}

/* The edges (faces around each, for edge pseudo-normals), the corners around each vertex (vertex
 * pseudo-normals) and whether the mesh is closed.  Returns 0, or -1 when out of memory. */
static int build_adjacency(sdc_body *b) {
    int64_t nf = b->nf, nv = b->nv, ns = 3 * nf, i, e = 0;
    sdc_pair *pairs = (sdc_pair *)malloc(sizeof(sdc_pair) * (size_t)(ns > 0 ? ns : 1));
    b->edge_of = (int64_t *)malloc(sizeof(int64_t) * (size_t)(ns > 0 ? ns : 1));
    b->eptr = (int64_t *)malloc(sizeof(int64_t) * (size_t)(ns + 1));
    b->eslot = (int64_t *)malloc(sizeof(int64_t) * (size_t)(ns > 0 ? ns : 1));
    b->vfptr = (int64_t *)calloc((size_t)(nv + 1), sizeof(int64_t));
    b->vcorner = (int64_t *)malloc(sizeof(int64_t) * (size_t)(ns > 0 ? ns : 1));
    if (!pairs || !b->edge_of || !b->eptr || !b->eslot || !b->vfptr || !b->vcorner) { free(pairs); return -1; }
    for (i = 0; i < ns; i++) {
        int64_t f = i / 3, c = i % 3;
        int64_t x = b->faces[3 * f + (c + 1) % 3], y = b->faces[3 * f + (c + 2) % 3];
        int64_t lo = x < y ? x : y, hi = x < y ? y : x;
        pairs[i].key = lo * (nv + 1) + hi;
        pairs[i].slot = i;
    }
    qsort(pairs, (size_t)ns, sizeof(sdc_pair), cmp_pair);
    b->closed = ns > 0;
    for (i = 0; i < ns;) {
        int64_t j = i;
        while (j < ns && pairs[j].key == pairs[i].key) j++;
        b->eptr[e] = i;
        {
            int64_t k;
            for (k = i; k < j; k++) {
                b->eslot[k] = pairs[k].slot;
                b->edge_of[pairs[k].slot] = e;
            }
        }
        if (j - i != 2) {
            b->closed = 0;
        } else {
            /* the two faces must run along the edge in opposite directions: compare where each starts */
            int64_t s0 = pairs[i].slot, s1 = pairs[i + 1].slot;
            int64_t a0 = b->faces[3 * (s0 / 3) + (s0 % 3 + 1) % 3], a1 = b->faces[3 * (s1 / 3) + (s1 % 3 + 1) % 3];
            if (a0 == a1) b->closed = 0;
        }
        e++;
        i = j;
    }
    b->eptr[e] = ns;
    free(pairs);
    /* corners per vertex, in ascending corner order (counting sort) */
    for (i = 0; i < ns; i++) b->vfptr[b->faces[i] + 1]++;
    for (i = 0; i < nv; i++) b->vfptr[i + 1] += b->vfptr[i];
    {
        int64_t *fill = (int64_t *)malloc(sizeof(int64_t) * (size_t)(nv > 0 ? nv : 1));
        if (!fill) return -1;
        for (i = 0; i < nv; i++) fill[i] = b->vfptr[i];
        for (i = 0; i < ns; i++) b->vcorner[fill[b->faces[i]]++] = i;
        free(fill);
    }
    return 0;
}

/* A collider for the mesh (vertices (V, 3) of one pose, faces (F, 3) with indices in [0, V)), or NULL when
 * out of memory or given an empty mesh.  Free it with sdc_free. */
SDC_API void *sdc_create(const double *verts, int64_t nv, const int64_t *faces, int64_t nf, int64_t leaf_size) {
    sdc_body *b;
    if (nv < 1 || nf < 1) return NULL;
    if (leaf_size < 1) leaf_size = 1;
    b = (sdc_body *)calloc(1, sizeof(sdc_body));
    if (!b) return NULL;
    b->nv = nv;
    b->nf = nf;
    b->faces = (int64_t *)malloc(sizeof(int64_t) * 3 * (size_t)nf);
    if (!b->faces) { free_body(b); return NULL; }
    memcpy(b->faces, faces, sizeof(int64_t) * 3 * (size_t)nf);
    if (build_tree(b, verts, leaf_size) != 0 || build_adjacency(b) != 0) { free_body(b); return NULL; }
    return b;
}

SDC_API void sdc_free(void *h) { free_body((sdc_body *)h); }

/* The version of this interface (the Python wrapper refuses a library built from another one). */
SDC_API int64_t sdc_abi(void) { return 6; } /* 6: sdc_push_out_carried; 5: pinched points deeper than SDC_PINCH stay; 4: sdc_near without the rule for buried skin */

SDC_API int64_t sdc_n_nodes(const void *h) { return ((const sdc_body *)h)->n_nodes; }

SDC_API int64_t sdc_depth(const void *h) { return ((const sdc_body *)h)->depth; }

SDC_API int64_t sdc_closed(const void *h) { return ((const sdc_body *)h)->closed; }

/* ---- refit -------------------------------------------------------------------------------------- */
/* The boxes (n_nodes, 6: lo xyz, hi xyz) of the tree at the posed vertices (V, 3) of one frame. */
SDC_API void sdc_refit(const void *h, const double *verts, double *box) {
    const sdc_body *b = (const sdc_body *)h;
    int64_t i, j;
    for (i = b->n_nodes - 1; i >= 0; i--) {
        double *o = box + 6 * i;
        /* in locals, with branch-free min/max: the comparisons are unpredictable */
        double x0, y0, z0, x1, y1, z1;
        if (b->left[i] < 0) {
            const double *p = verts + 3 * b->leaf_vert[b->vptr[i]];
            x0 = x1 = p[0];
            y0 = y1 = p[1];
            z0 = z1 = p[2];
            for (j = b->vptr[i] + 1; j < b->vptr[i + 1]; j++) {
                double x, y, z;
                p = verts + 3 * b->leaf_vert[j];
                x = p[0];
                y = p[1];
                z = p[2];
                x0 = x < x0 ? x : x0;
                y0 = y < y0 ? y : y0;
                z0 = z < z0 ? z : z0;
                x1 = x > x1 ? x : x1;
                y1 = y > y1 ? y : y1;
                z1 = z > z1 ? z : z1;
            }
        } else {
            const double *l = box + 6 * b->left[i], *r = box + 6 * b->right[i];
            x0 = l[0] < r[0] ? l[0] : r[0];
            y0 = l[1] < r[1] ? l[1] : r[1];
            z0 = l[2] < r[2] ? l[2] : r[2];
            x1 = l[3] > r[3] ? l[3] : r[3];
            y1 = l[4] > r[4] ? l[4] : r[4];
            z1 = l[5] > r[5] ? l[5] : r[5];
        }
        o[0] = x0;
        o[1] = y0;
        o[2] = z0;
        o[3] = x1;
        o[4] = y1;
        o[5] = z1;
    }
}

/* ---- geometry ----------------------------------------------------------------------------------- */
/* Closest point on triangle abc to p and its barycentric weights, as closest_point_on_triangles (the
 * reference): Voronoi regions in its order, its guards, weights clipped to [0, 1] and renormalised.
 * Returns the squared distance. */
static double closest_on_triangle(const double *p, const double *a, const double *b, const double *c,
                                  double *bary, double *out) {
    double ab[3], ac[3], ap[3], bp[3], cp[3], d1, d2, d3, d4, d5, d6, va, vb, vc, u, v, w, t, den, s, diff[3];
    sub3(b, a, ab);
    sub3(c, a, ac);
    sub3(p, a, ap);
    d1 = dot3(ab, ap);
    d2 = dot3(ac, ap);
    sub3(p, b, bp);
    d3 = dot3(ab, bp);
    d4 = dot3(ac, bp);
    sub3(p, c, cp);
    d5 = dot3(ab, cp);
    d6 = dot3(ac, cp);
    va = d3 * d6 - d5 * d4;
    vb = d5 * d2 - d1 * d6;
    vc = d1 * d4 - d3 * d2;
    if (d1 <= 0 && d2 <= 0) {
        u = 1; v = 0; w = 0;
    } else if (d3 >= 0 && d4 <= d3) {
        u = 0; v = 1; w = 0;
    } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        den = fabs(d1 - d3) > SDC_TINY ? d1 - d3 : SDC_TINY;
        t = d1 / den;
        u = 1 - t; v = t; w = 0;
    } else if (d6 >= 0 && d5 <= d6) {
        u = 0; v = 0; w = 1;
    } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        den = fabs(d2 - d6) > SDC_TINY ? d2 - d6 : SDC_TINY;
        t = d2 / den;
        u = 1 - t; v = 0; w = t;
    } else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        den = (d4 - d3) + (d5 - d6);
        den = fabs(den) > SDC_TINY ? den : SDC_TINY;
        t = (d4 - d3) / den;
        u = 0; v = 1 - t; w = t;
    } else {
        s = va + vb + vc;
        s = fabs(s) > SDC_TINY ? s : SDC_TINY;
        u = va / s; v = vb / s; w = vc / s;
    }
    /* clip to [0, 1] (NaN-free: the guards above keep every weight finite) and renormalise */
    u = u < 0 ? 0 : (u > 1 ? 1 : u);
    v = v < 0 ? 0 : (v > 1 ? 1 : v);
    w = w < 0 ? 0 : (w > 1 ? 1 : w);
    s = u + v + w;
    if (s < SDC_TINY) { u = 1; v = 0; w = 0; s = 1; } /* not reached for any triangle; a corner, never the origin */
    u /= s; v /= s; w /= s;
    out[0] = u * a[0] + v * b[0] + w * c[0];
    out[1] = u * a[1] + v * b[1] + w * c[1];
    out[2] = u * a[2] + v * b[2] + w * c[2];
    bary[0] = u; bary[1] = v; bary[2] = w;
    sub3(out, p, diff);
    return dot3(diff, diff);
}

/* Unit normal of face f (zero-area: the zero vector divided by 1e-300, i.e. zero). */
static void face_normal(const sdc_body *b, const double *verts, int64_t f, double *n) {
    const int64_t *t = b->faces + 3 * f;
    double e1[3], e2[3];
    sub3(verts + 3 * t[1], verts + 3 * t[0], e1);
    sub3(verts + 3 * t[2], verts + 3 * t[0], e2);
    cross3(e1, e2, n);
    normalize3(n);
}

/* Pseudo-normal of the feature of face f that the barycentric weights point at (module comment). */
static void feature_normal(const sdc_body *b, const double *verts, int64_t f, const double *bary, double *n) {
    int nz = (bary[0] > SDC_FEATURE) + (bary[1] > SDC_FEATURE) + (bary[2] > SDC_FEATURE);
    int64_t i;
    if (nz >= 3) {
        face_normal(b, verts, f, n);
    } else if (nz == 2) {
        /* the edge opposite the corner of least weight (the first of equal ones) */
        int c = 0;
        int64_t e;
        if (bary[1] < bary[c]) c = 1;
        if (bary[2] < bary[c]) c = 2;
        e = b->edge_of[3 * f + c];
        n[0] = n[1] = n[2] = 0;
        for (i = b->eptr[e]; i < b->eptr[e + 1]; i++) {
            double g[3];
            face_normal(b, verts, b->eslot[i] / 3, g);
            n[0] += g[0];
            n[1] += g[1];
            n[2] += g[2];
        }
        normalize3(n);
    } else {
        /* the vertex of greatest weight (the first of equal ones) */
        int c = 0;
        int64_t v;
        if (bary[1] > bary[c]) c = 1;
        if (bary[2] > bary[c]) c = 2;
        v = b->faces[3 * f + c];
        n[0] = n[1] = n[2] = 0;
        for (i = b->vfptr[v]; i < b->vfptr[v + 1]; i++) {
            int64_t corner = b->vcorner[i], g = corner / 3, k = corner % 3;
            const int64_t *t = b->faces + 3 * g;
            double e1[3], e2[3], fn[3], cosang, len, ang;
            sub3(verts + 3 * t[(k + 1) % 3], verts + 3 * t[k], e1);
            sub3(verts + 3 * t[(k + 2) % 3], verts + 3 * t[k], e2);
            len = norm3(e1) * norm3(e2);
            cosang = dot3(e1, e2) / (len > SDC_TINY ? len : SDC_TINY);
            cosang = cosang < -1 ? -1 : (cosang > 1 ? 1 : cosang);
            ang = sdc_acos(cosang);
            face_normal(b, verts, g, fn);
            n[0] += ang * fn[0];
            n[1] += ang * fn[1];
            n[2] += ang * fn[2];
        }
        normalize3(n);
    }
}

/* Squared distance from p to the box (lo xyz, hi xyz). */
static inline double box_dist2(const double *box, const double *p) {
    /* branch-free (the comparisons are unpredictable): max(lo - p, p - hi, 0) per axis; adding 0 changes no bit */
    double g0 = box[0] - p[0], h0 = p[0] - box[3], g1 = box[1] - p[1], h1 = p[1] - box[4];
    double g2 = box[2] - p[2], h2 = p[2] - box[5];
    g0 = h0 > g0 ? h0 : g0;
    g1 = h1 > g1 ? h1 : g1;
    g2 = h2 > g2 ? h2 : g2;
    g0 = g0 > 0 ? g0 : 0;
    g1 = g1 > 0 ? g1 : 0;
    g2 = g2 > 0 ? g2 : 0;
    return g0 * g0 + g1 * g1 + g2 * g2;
}

/* Per frame: the posed vertices, the refitted boxes and the slack of the pruning tests. */
typedef struct {
    const sdc_body *b;
    const double *verts, *box;
    double slack, scale;
} sdc_frame;

static void make_frame(const sdc_body *b, const double *verts, const double *box, sdc_frame *fr) {
    int k;
    double m = 0;
    fr->b = b;
    fr->verts = verts;
    fr->box = box;
    for (k = 0; k < 6; k++) {
        double x = fabs(box[k]);
        if (x > m) m = x;
    }
    /* scale: the posed body's size (its box's longest side), which the tolerances of the rules for buried skin and
     * the push-out's radius are measured in: the same wherever the body stands (the largest coordinate magnitude
     * made them 100x larger 100 m from the origin, and the cloth stage's frames 6.6 cm different there); slack: far
     * above the rounding of a distance at the largest coordinate magnitude (1e-16 of it) */
    fr->scale = 0;
    for (k = 0; k < 3; k++)
        if (box[3 + k] - box[k] > fr->scale) fr->scale = box[3 + k] - box[k];
    fr->slack = 1e-12 * m + SDC_TINY;
}

/* The nearest triangle to p with squared distance under the bound: branch and bound over the tree.
 * ub: the distance bound (inf: none).  On return *face is the winner (-1: none within the bound),
 * bary/closest its barycentric weights and point, and the squared distance is returned (inf: none).
 * open: only faces whose nearest point to p is not buried (nearest_open, below; buried is defined after
 * winding_at), at most SDC_BURY_TRIES of them tested. */
static int buried(const sdc_frame *fr, const double *c, int64_t f);
static double nearest_in(const sdc_frame *fr, const double *p, double ub, int open, int64_t *face, double *bary,
                         double *closest) {
    const sdc_body *b = fr->b;
    int64_t stack[SDC_STACK];
    double lbs[SDC_STACK];
    int top = 0;
    double best = INFINITY, slack = fr->slack, tb[3], tc[3], bound2;
    int64_t bestf = -1, tries = 0;
    int k;
    for (k = 0; k < 3; k++) /* a point far from the body rounds at its own magnitude */
        if (1e-12 * fabs(p[k]) > slack) slack = 1e-12 * fabs(p[k]);
    bound2 = (ub + slack) * (ub + slack); /* inf stays inf */
    stack[top] = 0;
    lbs[top++] = box_dist2(fr->box, p);
    while (top > 0) {
        int64_t node;
        top--;
        if (lbs[top] > bound2) continue;
        node = stack[top];
        if (b->left[node] < 0) {
            int64_t j;
            for (j = b->first[node]; j < b->first[node] + b->count[node]; j++) {
                int64_t f = b->leaf_face[j];
                const int64_t *t = b->faces + 3 * f;
                double r, d2 = closest_on_triangle(p, fr->verts + 3 * t[0], fr->verts + 3 * t[1],
                                                   fr->verts + 3 * t[2], tb, tc);
                if (!(d2 < best || (d2 == best && f < bestf) || bestf < 0)) continue; /* (bestf < 0: d2 overflowed) */
                if (open) {
                    if (++tries > SDC_BURY_TRIES) { /* bounded: the point keeps its closest surface */
                        *face = -1;
                        return INFINITY;
                    }
                    if (buried(fr, tc, f)) continue;
                }
                best = d2;
                bestf = f;
                bary[0] = tb[0]; bary[1] = tb[1]; bary[2] = tb[2];
                closest[0] = tc[0]; closest[1] = tc[1]; closest[2] = tc[2];
                r = sqrt(best) + slack;
                if (r * r < bound2) bound2 = r * r;
            }
        } else {
            int64_t l = b->left[node], r = b->right[node];
            double dl = box_dist2(fr->box + 6 * l, p), dr = box_dist2(fr->box + 6 * r, p);
            /* the nearer child is popped first */
            if (dl <= dr) {
                if (dr <= bound2) { stack[top] = r; lbs[top++] = dr; }
                if (dl <= bound2) { stack[top] = l; lbs[top++] = dl; }
            } else {
                if (dl <= bound2) { stack[top] = l; lbs[top++] = dl; }
                if (dr <= bound2) { stack[top] = r; lbs[top++] = dr; }
            }
        }
    }
    *face = bestf;
    return best;
}

static double nearest(const sdc_frame *fr, const double *p, double ub, int64_t *face, double *bary,
                      double *closest) {
    return nearest_in(fr, p, ub, 0, face, bary, closest);
}

/* A ray from p along +axis (dir 1) or -axis (dir -1) through the mesh: the signed count of its crossings
 * (0 outside a closed mesh), whether it passed exactly through an edge or a vertex or started on a
 * triangle's plane (*graze: the count is then not trusted), and the distance to its first crossing
 * (*first, inf: none): a surface point that far away. */
static int64_t ray_count(const sdc_frame *fr, const double *p, int axis, int dir, int *graze, double *first) {
    const sdc_body *b = fr->b;
    int u = (axis + 1) % 3, v = (axis + 2) % 3;
    int64_t stack[SDC_STACK], wind = 0;
    int top = 0;
    *graze = 0;
    *first = INFINITY;
    stack[top++] = 0;
    while (top > 0) {
        int64_t node = stack[--top];
        const double *bx = fr->box + 6 * node;
        if (p[u] < bx[u] || p[u] > bx[3 + u] || p[v] < bx[v] || p[v] > bx[3 + v]) continue;
        if (dir > 0 ? bx[3 + axis] < p[axis] : bx[axis] > p[axis]) continue;
        if (b->left[node] >= 0) {
            stack[top++] = b->right[node];
            stack[top++] = b->left[node];
            continue;
        }
        {
            int64_t j;
            for (j = b->first[node]; j < b->first[node] + b->count[node]; j++) {
                const int64_t *t = b->faces + 3 * b->leaf_face[j];
                const double *a = fr->verts + 3 * t[0], *bb = fr->verts + 3 * t[1], *c = fr->verts + 3 * t[2];
                double au = a[u] - p[u], av = a[v] - p[v], bu = bb[u] - p[u], bv = bb[v] - p[v];
                double cu = c[u] - p[u], cv = c[v] - p[v];
                /* 2-D edge functions: the same edge seen from its other face gives exactly the negative */
                double ea = bu * cv - bv * cu, eb = cu * av - cv * au, ec = au * bv - av * bu, s, num, depth;
                int pos = (ea > 0) + (eb > 0) + (ec > 0), neg = (ea < 0) + (eb < 0) + (ec < 0);
                if (pos && neg) continue; /* p's line misses the triangle */
                s = ea + eb + ec;
                if (s == 0) { /* the triangle is edge-on to the ray: a graze if the ray meets its own box */
                    double lo_u = au < bu ? au : bu, hi_u = au > bu ? au : bu, lo_v = av < bv ? av : bv;
                    double hi_v = av > bv ? av : bv, ea_ = a[axis], eb_ = bb[axis], ec_ = c[axis];
                    double far_ = dir > 0 ? (ea_ > eb_ ? ea_ : eb_) : (ea_ < eb_ ? ea_ : eb_);
                    lo_u = cu < lo_u ? cu : lo_u; hi_u = cu > hi_u ? cu : hi_u;
                    lo_v = cv < lo_v ? cv : lo_v; hi_v = cv > hi_v ? cv : hi_v;
                    far_ = dir > 0 ? (ec_ > far_ ? ec_ : far_) : (ec_ < far_ ? ec_ : far_);
                    if (lo_u <= 0 && hi_u >= 0 && lo_v <= 0 && hi_v >= 0 && (dir > 0 ? far_ >= p[axis] : far_ <= p[axis]))
                        *graze = 1;
                    continue;
                }
                num = ea * (a[axis] - p[axis]) + eb * (bb[axis] - p[axis]) + ec * (c[axis] - p[axis]);
                depth = dir * num / s;
                if (depth < 0) continue;
                if ((pos == 3 || neg == 3) && depth > 0) {
                    wind += (s > 0 ? 1 : -1) * dir;
                    if (depth < *first) *first = depth;
                } else {
                    *graze = 1; /* through an edge or a vertex, or from the triangle's plane */
                }
            }
        }
    }
    return wind;
}

/* The body's winding number at p when a ray decides it: the six axis directions, the shortest way out of the root box
 * first, until one does not graze.  Returns 1 with *w = |signed crossings| (0 outside, 1 inside, 2 where two parts
 * overlap), or 0 when all six graze or the body is not closed. */
static int winding_at(const sdc_frame *fr, const double *p, int64_t *w) {
    double dist[6], first;
    int used[6] = {0, 0, 0, 0, 0, 0}, tried, k, graze;
    if (!fr->b->closed) return 0;
    for (k = 0; k < 3; k++) {
        dist[2 * k] = fr->box[3 + k] - p[k];  /* +axis */
        dist[2 * k + 1] = p[k] - fr->box[k]; /* -axis */
    }
    for (tried = 0; tried < 6; tried++) {
        int best = -1;
        int64_t c;
        for (k = 0; k < 6; k++)
            if (!used[k] && (best < 0 || dist[k] < dist[best])) best = k;
        used[best] = 1;
        c = ray_count(fr, p, best / 2, best % 2 ? -1 : 1, &graze, &first);
        if (!graze) {
            *w = c < 0 ? -c : c;
            return 1;
        }
    }
    return 0;
}

/* Whether the point c of face f is buried: the point SDC_BURY * scale out from it along the face's normal is inside
 * the body by its winding number (undecided: not buried; a face of zero area: buried, never taken). */
static int buried(const sdc_frame *fr, const double *c, int64_t f) {
    double n[3], q[3], h = SDC_BURY * fr->scale;
    int64_t w;
    face_normal(fr->b, fr->verts, f, n);
    if (n[0] == 0 && n[1] == 0 && n[2] == 0) return 1; /* zero area: never open (its edges are its neighbours') */
    q[0] = c[0] + h * n[0];
    q[1] = c[1] + h * n[1];
    q[2] = c[2] + h * n[2];
    return winding_at(fr, q, &w) && w != 0;
}

/* As nearest within ub, over the faces whose nearest point to p is not buried: the minimum of (squared distance,
 * face index) over them, whatever the traversal (a face a little past ub, in a box within it, may be returned: the
 * caller checks the distance).  *face = -1 when every one is buried, or when more than
 * SDC_BURY_TRIES faces were tested (each test casts up to six rays: the cost per point is bounded; the point then
 * keeps its closest surface, as before the rule).  The reference tests the faces nearest first, stopping at the same
 * count; the kernel tests at least those (every face nearer than the answer is buried and tested), so the two can
 * differ only where the kernel reaches the cap. */
static double nearest_open(const sdc_frame *fr, const double *p, double ub, int64_t *face, double *bary,
                           double *closest) {
    return nearest_in(fr, p, ub, 1, face, bary, closest);
}

/* Signed distance at the closest point found (face f, weights bary, point closest) and the normal. */
static double signed_at(const sdc_frame *fr, const double *p, int64_t f, const double *bary, const double *closest,
                        double *n) {
    double diff[3], d;
    feature_normal(fr->b, fr->verts, f, bary, n);
    sub3(p, closest, diff);
    d = norm3(diff);
    return dot3(diff, n) < 0 ? -d : d;
}

/* A point p whose closest feature's side says outside (sd > SDC_BURY * scale: a point nearer the surface than that
 * is on it, as in buried) but whose winding number (wind, -1: not known yet)
 * says inside: its closest point becomes the nearest point that is not buried within ub, sd = minus the distance to
 * it and n that feature's pseudo-normal (module comment, "buried").  Otherwise (outside, undecided, nothing open, or
 * nothing open that near: pinched deeper) unchanged.  ub: SDC_PINCH * scale for the push-out, which leaves cloth
 * pinched deeper where it is; none (inf) for the backstop's traces, which ask only whether a point is still inside. */
static void unbury(const sdc_frame *fr, const double *p, int64_t wind, double ub, double *sd, double *closest,
                   double *n, int64_t *face) {
    double bary[3], c[3], d2;
    int64_t g;
    if (wind < 0 && !winding_at(fr, p, &wind)) return;
    if (wind == 0) return;
    d2 = nearest_open(fr, p, ub, &g, bary, c);
    if (g < 0 || d2 > ub * ub) return; /* pinched deeper: left */
    *face = g;
    closest[0] = c[0]; closest[1] = c[1]; closest[2] = c[2];
    feature_normal(fr->b, fr->verts, g, bary, n);
    *sd = -sqrt(d2);
}

/* The exact closest point of p if it is inside the body or within `radius` of it.  Returns 1 with the
 * signed distance, closest point, normal and face, or 0 when p is outside and farther than radius (a point farther
 * than radius that the winding number calls inside is found, with its closest surface).  The rule for buried skin
 * by `check`: 2 for every point (the push-out), 1 for the points farther than radius only (the ray that found them
 * inside is already cast: the cloth stage's backstop, which must not take a point in the torso for traced out), 0
 * for none (the cloth stage's contact lookups -- cloth pinched where an arm presses into the torso stays pinched in
 * its sweeps, as in the simulator, instead of each vertex taken alone across the arm: issue #26, flaps at a
 * dress's armholes; its final push-out applies the rule to the vertices in contact). */
static int near_or_inside(const sdc_frame *fr, const double *p, double radius, int check, double *sd,
                          double *closest, double *n, int64_t *face) {
    const sdc_body *b = fr->b;
    double bary[3], d2, bound = INFINITY;
    int64_t wind = -1; /* -1: not known */
    d2 = nearest(fr, p, radius, face, bary, closest);
    if (*face >= 0 && d2 < radius * radius) {
        *sd = signed_at(fr, p, *face, bary, closest, n);
        if (check == 2 && *sd > SDC_BURY * fr->scale)
            unbury(fr, p, wind, SDC_PINCH * fr->scale, sd, closest, n, face);
        return 1;
    }
    if (b->closed) {
        /* the shortest way out of the root box, along an axis */
        int axis = 0, dir = 1, k, graze;
        double best = INFINITY, first;
        for (k = 0; k < 3; k++) {
            double up = fr->box[3 + k] - p[k], down = p[k] - fr->box[k];
            if (up < best) { best = up; axis = k; dir = 1; }
            if (down < best) { best = down; axis = k; dir = -1; }
        }
        wind = ray_count(fr, p, axis, dir, &graze, &first);
        if (wind == 0 && !graze) return 0;
        wind = graze ? -1 : (wind < 0 ? -wind : wind); /* |signed crossings|; -1: not known */
        bound = first;
    }
    nearest(fr, p, bound, face, bary, closest);
    /* none within the bound: the ray's first hit, measured on a nearly edge-on triangle, came out short */
    if (*face < 0) nearest(fr, p, INFINITY, face, bary, closest);
    *sd = signed_at(fr, p, *face, bary, closest, n);
    if (check >= 1 && *sd > SDC_BURY * fr->scale)
        unbury(fr, p, wind, check == 2 ? SDC_PINCH * fr->scale : INFINITY, sd, closest, n, face);
    return 1;
}

/* ---- entry points ------------------------------------------------------------------------------- */
/* Exact signed distance (negative inside), closest point, outward normal and face of the points
 * [i0, i1) of pts (P, 3) against one frame: verts (V, 3) with its boxes from sdc_refit. */
SDC_API void sdc_query(const void *h, const double *verts, const double *box, const double *pts, int64_t i0,
                       int64_t i1, double *sd, double *closest, double *normal, int64_t *face) {
    sdc_frame fr;
    int64_t i;
    make_frame((const sdc_body *)h, verts, box, &fr);
    for (i = i0; i < i1; i++) {
        double bary[3];
        nearest(&fr, pts + 3 * i, INFINITY, face + i, bary, closest + 3 * i);
        sd[i] = signed_at(&fr, pts + 3 * i, face[i], bary, closest + 3 * i, normal + 3 * i);
    }
}

/* The exact signed distance, closest point and outward normal of every point of pts [i0, i1) that is inside the
 * body or within `radius` of it, against one frame (verts with its boxes from sdc_refit); the others get
 * sd = +inf (their closest point and normal are not defined).  Returns how many were found.  The cloth stage's
 * lookups (_cloth.c): with `rule` 0 (its contacts) no rule for buried skin -- a point farther than radius that the
 * winding number calls inside gets its closest surface, whose side may say outside; with 1 (its backstop's traces)
 * the rule for the points farther than radius (near_or_inside). */
SDC_API int64_t sdc_near(const void *h, const double *verts, const double *box, const double *pts, int64_t i0,
                         int64_t i1, double radius, double *sd, double *closest, double *normal, int64_t rule) {
    sdc_frame fr;
    int64_t i, face, found = 0;
    make_frame((const sdc_body *)h, verts, box, &fr);
    for (i = i0; i < i1; i++) {
        if (near_or_inside(&fr, pts + 3 * i, radius, rule ? 1 : 0, sd + i, closest + 3 * i, normal + 3 * i, &face))
            found++;
        else
            sd[i] = INFINITY;
    }
    return found;
}

/* The body's winding number at the points [i0, i1) of pts against one frame (verts with its boxes from sdc_refit):
 * 0 outside, 1 inside, 2 where two parts of a posed body that intersects itself overlap (an arm pressed into the
 * torso).  The signed crossings of a ray along the shortest way out of the root box; when it grazes an edge or a
 * vertex, the next of the six axis directions (the shortest first).  A point whose six rays all graze, or any point
 * of a body that is not closed, gets the closest point's side instead (1 inside, 0 outside).  Unlike the signed
 * distance's side, which the closest surface decides, this is inside for a point in the torso whose closest surface
 * is the buried skin of an arm inside it.  Returns how many points took the closest point's side.  (The evaluation's
 * penetration metric; the push-out's rule for buried surfaces decides inside the same way, by winding_at.) */
SDC_API int64_t sdc_winding(const void *h, const double *verts, const double *box, const double *pts, int64_t i0,
                            int64_t i1, int64_t *wind) {
    sdc_frame fr;
    int64_t i, fell = 0;
    make_frame((const sdc_body *)h, verts, box, &fr);
    for (i = i0; i < i1; i++) {
        const double *p = pts + 3 * i;
        if (!winding_at(&fr, p, wind + i)) {
            double bary[3], closest[3], n[3];
            int64_t face;
            nearest(&fr, p, INFINITY, &face, bary, closest);
            wind[i] = signed_at(&fr, p, face, bary, closest, n) < 0 ? 1 : 0;
            fell++;
        }
    }
    return fell;
}

/* The push-out of one point p (moved in place), up to `iterations` passes; 1 if it moved. */
static int push_point(const sdc_frame *fr, double *p, double radius, double margin, int64_t iterations) {
    int64_t it, face;
    int moved = 0;
    for (it = 0; it < iterations; it++) {
        double sd, c[3], nrm[3];
        if (!near_or_inside(fr, p, radius, 2, &sd, c, nrm, &face) || !(sd < margin)) break;
        p[0] = c[0] + margin * nrm[0];
        p[1] = c[1] + margin * nrm[1];
        p[2] = c[2] + margin * nrm[2];
        moved = 1;
    }
    return moved;
}

/* The rule for the correction carried from the frame before (sdc_push_out_carried), for one point: q its place
 * before the push-out, p (in place) its place after it, k0 (in place) the correction p - q of the frame before
 * (zero: none).  Where the push-out's correction k = p - q differs from k0 by more than lim = SDC_PINCH * scale (the
 * point's closest exit is on another side of a limb than the frame before's: it is deep in it), the push-out is
 * tried again from q + k0 and from q + k0 / 2, and the exit whose correction is nearest k0 is kept -- nearer than
 * k's, with a move at most SDC_CARRY_LIMB |k| + lim (not across the body: a move carried frame after frame grew
 * to 18 cm on a skirt) and at most |k0| + SDC_CARRY_GROW lim.  Every exit is a push-out's, so the rule never leaves
 * a point inside that the push-out takes out; the half step lets a correction the network no longer needs fade
 * over a few frames instead of in one.  Then k0 = p - q. */
static void carry_point(const sdc_frame *fr, const double *q, double *p, double *k0, double radius, double margin,
                        int64_t iterations) {
    static const double gain[2] = {1.0, 0.5};
    double k[3], d[3], lim = SDC_PINCH * fr->scale;
    int g;
    sub3(p, q, k);
    if (k0[0] != 0.0 || k0[1] != 0.0 || k0[2] != 0.0) {
        double best;
        sub3(k, k0, d);
        best = norm3(d);
        if (best > lim) {
            double kn = norm3(k), k0n = norm3(k0), a[3], ka[3], pick[3];
            pick[0] = p[0]; pick[1] = p[1]; pick[2] = p[2];
            for (g = 0; g < 2; g++) {
                double an, dn;
                a[0] = q[0] + gain[g] * k0[0];
                a[1] = q[1] + gain[g] * k0[1];
                a[2] = q[2] + gain[g] * k0[2];
                push_point(fr, a, radius, margin, iterations);
                sub3(a, q, ka);
                sub3(ka, k0, d);
                dn = norm3(d);
                an = norm3(ka);
                if (dn < best && an <= SDC_CARRY_LIMB * kn + lim && an <= k0n + SDC_CARRY_GROW * lim) {
                    best = dn;
                    pick[0] = a[0]; pick[1] = a[1]; pick[2] = a[2];
                }
            }
            p[0] = pick[0]; p[1] = pick[1]; p[2] = pick[2];
        }
    }
    sub3(p, q, k0);
}

/* The push-out of the points [i0, i1) of every frame of pts (B, N, 3), in place, against verts (B, V, 3) with boxes
 * (B, n_nodes, 6) from sdc_refit; with carry (N, 3) not NULL the correction carried from frame to frame
 * (carry_point) and a point counted as moved where its place changed, else where a pass moved it.  moved (B, N) set
 * to 1 for every point moved (others are left as they are).  Returns the number of points newly marked. */
static int64_t push_frames(const sdc_body *b, const double *verts, const double *box, int64_t nb, double *pts,
                           int64_t n, int64_t i0, int64_t i1, double margin, int64_t iterations, uint8_t *moved,
                           double *carry) {
    int64_t f, i, total = 0;
    if (iterations < 1) iterations = 1;
    for (f = 0; f < nb; f++) {
        sdc_frame fr;
        double radius;
        make_frame(b, verts + 3 * b->nv * f, box + 6 * b->n_nodes * f, &fr);
        /* a little over the margin: a point just pushed out to the margin is found again by the radius */
        radius = margin * (1.0 + 1e-3) + 1e-9 * fr.scale;
        for (i = i0; i < i1; i++) {
            double *p = pts + 3 * (n * f + i), q[3];
            int changed;
            q[0] = p[0]; q[1] = p[1]; q[2] = p[2];
            changed = push_point(&fr, p, radius, margin, iterations);
            if (carry) {
                carry_point(&fr, q, p, carry + 3 * i, radius, margin, iterations);
                changed = p[0] != q[0] || p[1] != q[1] || p[2] != q[2];
            }
            if (changed && !moved[n * f + i]) {
                moved[n * f + i] = 1;
                total++;
            }
        }
    }
    return total;
}

/* sdc_push_out with the correction carried from frame to frame (the collision stage's rule since 30 Nov 2026,
 * eighth session): the frames of pts (B, N, 3) are consecutive, carry (N, 3) holds each point's correction (its place after minus before)
 * of the frame before the first (zero: none) and is left holding the last frame's; carry_point's rule after each
 * point's push-out.  moved (B, N): 1 where the point's place changed.  Points are independent: disjoint ranges
 * [i0, i1) may run on as many threads as the caller likes, and a stream cut into batches anywhere gives the frames
 * of one call.  Returns the number of points moved.  Measured on ten garment x CMU-clip pairs of real motion
 * (docs/cloth-eval.md): the vertex-frames that step more than 3 cm and 3x the network's step 1,085 -> 519. */
SDC_API int64_t sdc_push_out_carried(const void *h, const double *verts, const double *box, int64_t nb, double *pts,
                                     int64_t n, int64_t i0, int64_t i1, double margin, int64_t iterations,
                                     uint8_t *moved, double *carry) {
    return push_frames((const sdc_body *)h, verts, box, nb, pts, n, i0, i1, margin, iterations, moved, carry);
}

/* push_out of the points [i0, i1) of every frame: pts (B, N, 3) moved in place against verts (B, V, 3)
 * with boxes (B, n_nodes, 6) from sdc_refit; moved (B, N) set to 1 for every point moved (others are left
 * as they are).  Returns the number of points moved. */
SDC_API int64_t sdc_push_out(const void *h, const double *verts, const double *box, int64_t nb, double *pts,
                             int64_t n, int64_t i0, int64_t i1, double margin, int64_t iterations,
                             uint8_t *moved) {
    return push_frames((const sdc_body *)h, verts, box, nb, pts, n, i0, i1, margin, iterations, moved, NULL);
}

/* ---- the Python extension module ---------------------------------------------------------------- */
/* Built as the (empty) module segadeform.body._collide so that setuptools compiles it at install; the
 * functions above are reached through ctypes.  Other builds leave SDC_PYTHON_MODULE undefined. */
#ifdef SDC_PYTHON_MODULE
static struct PyModuleDef sdc_module = {PyModuleDef_HEAD_INIT, "_collide",
                                        "segadeform's compiled collision kernel (called through ctypes).", -1,
                                        NULL, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__collide(void) { return PyModule_Create(&sdc_module); }
#endif
