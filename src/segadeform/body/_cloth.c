/*
 * The cloth stage, compiled: a few position-based constraint sweeps after the network that make a garment behave
 * like cloth against the posed body while it follows the network's frame (the target) where it lies on the body.
 *
 * Portable C99 with no dependencies besides the body collider it calls (_collide.c: the C++ runtime compiles both
 * files into one program, setup.py builds both into the extension segadeform.body._cloth, and
 * runtimes/node/src/cloth.js ports this file line for line for Node and the browser).  Plain loops over plain
 * arrays, float64 arithmetic using only + - * / and sqrt (correctly rounded everywhere), no threads, no libm
 * function that rounds differently per platform.  Compile without floating-point contraction
 * (-ffp-contract=off) so that every platform rounds alike.  Deterministic: the same inputs give the same bits.
 *
 * The method is position-based dynamics (Mueller, Heidelberger, Hennix & Ratcliff, "Position based dynamics",
 * VRIPHYS 2006 / J. Vis. Commun. Image R. 2007): predict positions from the previous output frames (inertia and
 * gravity), then project constraints one after another (Gauss-Seidel), a few sweeps; a constraint's stiffness k
 * is applied per sweep as 1 - (1 - k)^(1/sweeps) so that the number of sweeps changes how well the constraints
 * are met, not how stiff they are.  The constraints, in the order each sweep projects them:
 *
 *   stretch       every edge's length kept within [(1 - compress) L0, (1 + stretch) L0] of its rest length L0:
 *                 strain limiting (Provot, "Deformation constraints in a mass-spring model to describe rigid
 *                 cloth behavior", Graphics Interface 1995), stiffness `stiffness`;
 *   tethers       every free vertex kept within (1 + stretch) G of its anchor, the attached vertex nearest to it
 *                 along the rest mesh's edges (G: that path's rest length; scl_setup), stiffness `stiffness`: long
 *                 range attachments (Kim, Chentanez & Mueller, "Long range attachments - a method to simulate
 *                 inextensible clothing in computer games", SCA 2012).  A few sweeps of edges alone cannot carry a
 *                 pull along a hanging chain of many edges, so without them gravity and inertia stretch the cloth
 *                 below the attached vertices every frame;
 *   smoothing     each free vertex's deviation from the target (x - y) moved toward the mean deviation of its
 *                 neighbours, stiffness `bending`: the target's Laplacian coordinates are kept (Sorkine et al.,
 *                 "Laplacian surface editing", SGP 2004), so the network's folds stay while a displacement made
 *                 by a contact spreads to the neighbours instead of moving one vertex alone;
 *   attachment    every vertex within radius[i] of its target (the engines' "max distance" or motion
 *                 constraint: Unreal Chaos Cloth, NvCloth): radius 0 where the garment lies on the body at
 *                 rest (it follows the network exactly), growing with the rest distance from the body to at
 *                 most max_distance on hems and loose parts (scl_setup);
 *   contact       every vertex found at the frame's start inside the body or within margin + SCL_CONTACT_BAND
 *                 of it kept on the outer side of the plane through its closest body point: n . (x - c) >= margin;
 *   edge contact  the same for the middle of every edge with an end in contact and a free end, found within the
 *                 band and not deeper inside than SCL_EDGE_DEEP (2 cm; deeper, a limb is through the cloth and the
 *                 middle's closest surface may be either side of it: its ends' contacts and the push-out take
 *                 them out): both ends moved
 *                 alike along the plane's normal, n . ((xa + xb) / 2 - c) >= margin (a vertex-edge contact with
 *                 equal masses: Bridson, Fedkiw & Anderson, "Robust treatment of collisions, contact and friction
 *                 for cloth animation", SIGGRAPH 2002, sec. 7).  Without it two ends pushed out to either side of a
 *                 limb leave the edge between them across it: the holes of a thigh through a skirt, every vertex
 *                 outside.  An edge with both ends attached gets the plane only where both ends are in contact on
 *                 the same side of the body and its middle too (the three contact normals within 60 degrees of each
 *                 other, SCL_AGREE), and the body may bulge into its middle by more than the ends' room and a
 *                 quarter of the margin (edge_near): a tight garment's long edge across a bent knee, whose middle
 *                 the knee comes through while both ends lie on it.  Elsewhere such an edge is left to the vertex
 *                 contacts: it follows the network where the garment lies on the body, and in a pinch (an arm
 *                 against the torso, ends or middle closest to different parts) no side is the outside.
 *
 * Deep targets (the backstop, after the engines' backstop of Unreal Chaos Cloth: the cloth kept on the outer side
 * of the body along the skinned normal): where the network puts the garment deep inside the body (a thigh 3-8 cm
 * through a skirt), the closest body point sends the vertices on either side of the limb's middle to opposite
 * sides of it and the edges between them across it.  So when a loose vertex's target (attachment radius at
 * least SCL_LOOSE, 7 mm: cloth that hangs away from the body at rest; a sleeve's hem lying on the arm, radius a
 * few millimetres, keeps the closest-point rule -- traced along its normal it ran along the arm and popped 10-17 cm
 * for a few frames; 7 mm rather than the 1 cm of ABI 13: 3,450 -> 3,315 pops on ten garment x CMU-clip pairs,
 * docs/cloth-eval.md) is deeper than `backstop` inside and its prediction inside too, the frame's start moves the target
 * instead (the target's depth, looked up for the loose vertices every frame, not the prediction's: the prediction
 * follows the frame before's output, so a vertex traced out one frame was predicted shallower the next, left to its
 * closest exit on the other side of the limb, deep again the frame after -- a jacket's panel in a hip under a
 * karate form flipped front to back every other frame, and a still panel in a still limb never settled): each such vertex's target is sphere-traced out of the body along the
 * garment's outward normal there (one side for a whole panel: the normal of the target's faces, oriented by a
 * vote of the vertices just outside the body, n . body normal), at most SCL_TRACE steps of (margin - sd + 1 mm),
 * and no farther than SCL_REACH (20 cm: a longer trace went through the torso, not out of a limb: dropped);
 * the moves of those that came out are spread over the garment within SCL_SPREAD_RADIUS of them (along the
 * target's edges) by SCL_SPREAD Jacobi sweeps of the mean over each vertex's neighbours (the traced ones held, the
 * move 0 beyond the radius: a smooth, harmonic falloff, so that the cloth around a thigh moves with it as a tent); the target and the prediction both take the spread move, and the contacts are
 * found again.  Frames with no loose vertex pay one comparison per vertex; the others one lookup (inside or not) of
 * each loose vertex's target.
 *
 * After the sweeps, the vertices that may be inside the body or closer than the margin -- found so, or moved
 * farther than their clearance since the contacts were found (no other can be, except a vertex pinched where the
 * body intersects itself, below, which stays where it was found) -- are pushed out of the body exactly as the
 * collision stage does (sdc_push_out, SCL_PASSES passes): contact wins over the attachment (edge middles are not
 * pushed there: the planes above hold them).  When it moved a vertex, the frame settles:
 * `iterations` more sweeps of the stretch limits, each followed by the attachment (no contact planes; a free vertex
 * may stay as far from its target as the sweeps and the push-out left it), with the vertices it moved held where
 * it put them, carry their free neighbours along instead of leaving the edges between
 * them stretched (on held-out dresses, a skirt and a sleeved dress of issue #26: 10-26 % fewer edge-frames
 * stretched more than 10 points past both the limit and the network's own stretch), and the vertices they moved
 * that may be inside or within the margin (the final push-out's test) are pushed out again.  The contact lookups (sdc_near) do not apply the
 * collider's rule for buried skin: cloth pinched where an arm presses into the torso, inside by the body's winding
 * number but outside the skin nearest it, stays pinched, as the simulator leaves it, instead of being taken across
 * the arm one vertex at a time (flaps at a dress's armholes); the final push-out applies the rule to the vertices
 * it moves (those in contact among them).  Attached vertices
 * (radius 0) have infinite mass for the stretch limits, tethers and smoothing, which move only free vertices;
 * contacts, at vertices and edge middles, move any vertex.
 *
 * Seams: vertices at exactly the same rest position (a mesh split along a seam: game-engine exports split vertices
 * at UV seams) are one point of cloth.  scl_setup gives each its group's lowest index (weld), builds the edges on
 * the faces through it (the edges of the mesh as if it had never been split) and the backstop's normals come from
 * those faces too; each frame ends with every other vertex of a group put where the group's lowest one is, so that a
 * seam's two sides move as one (split at a seam, a dress on a walk tore 7 cm at its seam: 2 Dec 2026).
 *
 * State (the caller keeps it between calls; calls may hold any number of frames): the last two output frames and
 * the last target.  Inertia: p = x1 + (1 - damping)(x1 - x0) - (0, gravity dt^2, 0), from the frames before, then
 * p += follow (y - p) (a drive toward the target: the deviation decays instead of staying at the bound); the
 * first frame, and a frame whose target moved more than `reset` metres on average since the last one (a body
 * that teleports), start from the target with no velocity (a reset, counted).
 */

#ifdef SCL_PYTHON_MODULE
#include <Python.h> /* first, as Python asks; only for the empty module at the end of the file */
#endif
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#if defined(_WIN32)
#define SCL_API __declspec(dllexport)
#else
#define SCL_API __attribute__((visibility("default")))
#endif

/* the body collider: _collide.c's entry points (compiled into the same library or program) */
int64_t sdc_n_nodes(const void *h);
void sdc_refit(const void *h, const double *verts, double *box);
int64_t sdc_near(const void *h, const double *verts, const double *box, const double *pts, int64_t i0, int64_t i1,
                 double radius, double *sd, double *closest, double *normal, int64_t rule);
int64_t sdc_push_out(const void *h, const double *verts, const double *box, int64_t nb, double *pts, int64_t n,
                     int64_t i0, int64_t i1, double margin, int64_t iterations, uint8_t *moved);

#define SCL_ABI 15 /* 15: vertices at one rest position welded (scl_setup's weld, scl_step's); 14: SCL_LOOSE 7 mm (was 1 cm); 13: the backstop picks the loose vertices whose target (not prediction) is deeper than `backstop`
                       * inside; 12: an edge middle deeper than SCL_EDGE_DEEP inside gets no contact plane, a backstop trace
                       * longer than SCL_REACH is dropped; 11: the collision kernel it embeds leaves cloth pinched deeper than SDC_PINCH; 10: every frame
                       * checked for NaN and inf before any is stepped (the state unchanged on one); 9: its contact
                       * lookups leave pinched cloth pinched (the rule for buried skin only in the final
                       * push-out and the backstop's traces), and settling sweeps after the push-out; 8: the collision kernel it embeds pushes off buried surfaces (1 Dec 2026); 7: its own acos */
#define SCL_CONTACT_BAND 0.005 /* metres beyond the margin within which a vertex gets a contact plane */
#define SCL_EDGE_DEEP 0.02     /* metres: an edge middle found deeper inside than this gets no contact plane */
#define SCL_PASSES 3          /* the final push-out's passes: segadeform.body.collision.push_out's */
#define SCL_TINY 1e-300
#define SCL_MOVED 1e-6        /* metres: a final push-out move counted as one (not a vertex already at the margin) */
#define SCL_TRACE 8           /* the backstop's sphere-tracing steps */
#define SCL_LOOSE 0.007       /* the backstop traces vertices whose attachment radius is at least this (m) */
#define SCL_OVERSHOOT 0.001   /* metres past the margin each tracing step aims */
#define SCL_REACH 0.2         /* metres: a backstop trace longer than this went through the torso: dropped */
#define SCL_SPREAD 40         /* Jacobi sweeps spreading the traced moves over the garment */
#define SCL_SPREAD_RADIUS 0.2 /* metres along the garment from a traced vertex that its move spreads to */
#define SCL_AGREE 0.5         /* cosine: contact normals within 60 degrees are on the same side of the body */

/* the settings array's entries (segadeform.body.cloth.ClothSettings.array) */
enum {
    S_ITERATIONS, /* sweeps per frame, >= 1 */
    S_STIFFNESS,  /* stretch stiffness in [0, 1] */
    S_STRETCH,    /* an edge may be at most (1 + stretch) L0 */
    S_COMPRESS,   /* and at least (1 - compress) L0 */
    S_BENDING,    /* smoothing stiffness in [0, 1] */
    S_DAMPING,    /* fraction of the velocity lost per frame */
    S_GRAVITY,    /* m/s^2 along -y */
    S_DT,         /* seconds per frame */
    S_MARGIN,     /* metres kept between garment and body */
    S_RESET,      /* metres of mean target motion in one frame that reset the state */
    S_FOLLOW,     /* fraction of the predicted deviation from the target removed per frame */
    S_BACKSTOP,   /* metres: a prediction deeper than this inside the body has its target traced out (0: off) */
    S_COUNT
};

/* info array entries (in and out) */
enum { I_HAVE, I_RESETS, I_CONTACTS, I_PUSHED, I_FIRST_RESET, I_TRACED, I_COUNT };

SCL_API int64_t scl_abi(void) { return SCL_ABI; }

SCL_API int64_t scl_n_settings(void) { return S_COUNT; }

/* ---- per garment ---------------------------------------------------------------------------------------- */
typedef struct {
    int64_t a, b;
} scl_edge;

static int cmp_edge(const void *x, const void *y) {
    const scl_edge *p = (const scl_edge *)x, *q = (const scl_edge *)y;
    if (p->a != q->a) return p->a < q->a ? -1 : 1;
    return p->b < q->b ? -1 : (p->b > q->b ? 1 : 0);
}

typedef struct {
    double x, y, z;
    int64_t i;
} scl_point;

static int cmp_point(const void *u, const void *v) {
    const scl_point *p = (const scl_point *)u, *q = (const scl_point *)v;
    if (p->x != q->x) return p->x < q->x ? -1 : 1;
    if (p->y != q->y) return p->y < q->y ? -1 : 1;
    if (p->z != q->z) return p->z < q->z ? -1 : 1;
    return p->i < q->i ? -1 : (p->i > q->i ? 1 : 0);
}

/* Each vertex's weld (N,): the lowest index of the vertices at exactly its rest position (itself when none other
 * is there).  Returns 0, -1 when out of memory. */
static int64_t scl_weld(const double *rest, int64_t n, int64_t *weld) {
    int64_t i, first = 0;
    scl_point *p = (scl_point *)malloc(sizeof(scl_point) * (size_t)n);
    if (!p) return -1;
    for (i = 0; i < n; i++) {
        p[i].x = rest[3 * i];
        p[i].y = rest[3 * i + 1];
        p[i].z = rest[3 * i + 2];
        p[i].i = i;
    }
    qsort(p, (size_t)n, sizeof(scl_point), cmp_point);
    for (i = 0; i < n; i++) {
        if (i > 0 && !(p[i].x == p[i - 1].x && p[i].y == p[i - 1].y && p[i].z == p[i - 1].z)) first = i;
        weld[p[i].i] = p[first].i; /* sorted by index within a group: its first is its lowest */
    }
    free(p);
    return 0;
}

/* The per-garment data from the rest garment rest (N, 3), faces (F, 3) and each vertex's signed distance from
 * the body at rest rest_sd (N,) (negative inside):
 *   weld (N,)        each vertex's group: the lowest index of the vertices at exactly its rest position (scl_weld);
 *   edges (E, 2)     the distinct edges (a < b) of the faces through weld (a seam's two sides joined), sorted by
 *                    (a, b); a face's repeated vertex makes none;
 *   rest_len (E,)    their rest lengths;
 *   nptr (N + 1), nidx (2E)  each vertex's neighbours nidx[nptr[i]:nptr[i + 1]], ascending;
 *   radius (N,)      how far each vertex may leave its target: 0 within `attachment` of the body at rest, else
 *                    min(max_distance, rest_sd - attachment);
 *   anchor (N,)      each free vertex's tether anchor: the attached vertex (radius 0) nearest to it along the edges
 *                    (Dijkstra's shortest paths from all attached vertices at once, scl_tethers), -1 for attached
 *                    vertices and those no attached vertex reaches;
 *   tether (N,)      the rest length of that path (0 where anchor is -1).
 * The caller sizes edges for 3F pairs, rest_len for 3F, nidx for 6F.  Returns E, -1 when out of memory, -2 for a
 * face index outside [0, N). */
typedef struct {
    double d;
    int64_t v;
} scl_item;

/* the heap's order: by distance, then by vertex (a total order: every heap pops the same sequence) */
static int item_less(const scl_item *p, const scl_item *q) { return p->d < q->d || (p->d == q->d && p->v < q->v); }

static void heap_push(scl_item *h, int64_t *len, double d, int64_t v) {
    int64_t c = (*len)++;
    while (c > 0) {
        int64_t up = (c - 1) / 2;
        scl_item it;
        it.d = d;
        it.v = v;
        if (!item_less(&it, &h[up])) break;
        h[c] = h[up];
        c = up;
    }
    h[c].d = d;
    h[c].v = v;
}

static scl_item heap_pop(scl_item *h, int64_t *len) {
    scl_item top = h[0], last = h[--(*len)];
    int64_t c = 0;
    for (;;) {
        int64_t l = 2 * c + 1, r = l + 1, s = c;
        const scl_item *best = &last;
        if (l < *len && item_less(&h[l], best)) { s = l; best = &h[l]; }
        if (r < *len && item_less(&h[r], best)) s = r;
        if (s == c) break;
        h[c] = h[s];
        c = s;
    }
    if (*len > 0) h[c] = last;
    return top;
}

/* The tethers: Dijkstra from every attached vertex at once over the edges' rest lengths (|rest[b] - rest[a]|,
 * a < b, as rest_len), a vertex settled in (distance, index) order; a neighbour takes the settled vertex's anchor
 * when its path is shorter, or as short with a smaller anchor.  Returns 0, -1 when out of memory. */
static int64_t scl_tethers(const double *rest, int64_t n, const int64_t *nptr, const int64_t *nidx,
                           const double *radius, int64_t *anchor, double *tether) {
    scl_item *h = (scl_item *)malloc(sizeof(scl_item) * (size_t)(n + nptr[n]));
    uint8_t *done = (uint8_t *)malloc((size_t)n);
    int64_t i, j, len = 0;
    if (!h || !done) { free(h); free(done); return -1; }
    for (i = 0; i < n; i++) {
        done[i] = 0;
        tether[i] = 0.0;
        anchor[i] = radius[i] > 0 ? -1 : i;
        if (anchor[i] >= 0) heap_push(h, &len, 0.0, i);
    }
    while (len > 0) {
        scl_item it = heap_pop(h, &len);
        int64_t v = it.v;
        if (done[v] || it.d > tether[v]) continue; /* settled, or a longer path found before a shorter one */
        done[v] = 1;
        for (j = nptr[v]; j < nptr[v + 1]; j++) {
            int64_t w = nidx[j], a = v < w ? v : w, b = v < w ? w : v;
            double dx = rest[3 * b] - rest[3 * a], dy = rest[3 * b + 1] - rest[3 * a + 1];
            double dz = rest[3 * b + 2] - rest[3 * a + 2], c;
            if (done[w]) continue;
            c = it.d + sqrt(dx * dx + dy * dy + dz * dz);
            if (anchor[w] < 0 || c < tether[w]) {
                tether[w] = c;
                anchor[w] = anchor[v];
                heap_push(h, &len, c, w);
            } else if (c == tether[w] && anchor[v] < anchor[w]) {
                anchor[w] = anchor[v];
            }
        }
    }
    for (i = 0; i < n; i++)
        if (!(radius[i] > 0)) anchor[i] = -1; /* attached: no tether (its distance is 0) */
    free(h);
    free(done);
    return 0;
}

SCL_API int64_t scl_setup(const double *rest, int64_t n, const int64_t *faces, int64_t nf, const double *rest_sd,
                          double attachment, double max_distance, int64_t *edges, double *rest_len, int64_t *nptr,
                          int64_t *nidx, double *radius, int64_t *anchor, double *tether, int64_t *weld) {
    scl_edge *e;
    int64_t *fill;
    int64_t i, k, ne = 0, m = 0;
    if (n < 1 || nf < 0) return -2;
    for (i = 0; i < 3 * nf; i++)
        if (faces[i] < 0 || faces[i] >= n) return -2;
    if (scl_weld(rest, n, weld) < 0) return -1;
    e = (scl_edge *)malloc(sizeof(scl_edge) * (size_t)(nf > 0 ? 3 * nf : 1));
    fill = (int64_t *)malloc(sizeof(int64_t) * (size_t)n);
    if (!e || !fill) { free(e); free(fill); return -1; }
    for (i = 0; i < nf; i++)
        for (k = 0; k < 3; k++) {
            int64_t x = weld[faces[3 * i + k]], y = weld[faces[3 * i + (k + 1) % 3]];
            if (x == y) continue;
            e[ne].a = x < y ? x : y;
            e[ne].b = x < y ? y : x;
            ne++;
        }
    qsort(e, (size_t)ne, sizeof(scl_edge), cmp_edge);
    for (i = 0; i < ne; i++)
        if (m == 0 || e[i].a != e[m - 1].a || e[i].b != e[m - 1].b) e[m++] = e[i];
    ne = m;
    for (i = 0; i < ne; i++) {
        const double *p = rest + 3 * e[i].a, *q = rest + 3 * e[i].b;
        double dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
        edges[2 * i] = e[i].a;
        edges[2 * i + 1] = e[i].b;
        rest_len[i] = sqrt(dx * dx + dy * dy + dz * dz);
    }
    for (i = 0; i <= n; i++) nptr[i] = 0;
    for (i = 0; i < ne; i++) {
        nptr[e[i].a + 1]++;
        nptr[e[i].b + 1]++;
    }
    for (i = 0; i < n; i++) nptr[i + 1] += nptr[i];
    for (i = 0; i < n; i++) fill[i] = nptr[i];
    /* edges sorted by (a, b): a vertex meets its smaller neighbours (as b) before its larger ones (as a) */
    for (i = 0; i < ne; i++) {
        nidx[fill[e[i].a]++] = e[i].b;
        nidx[fill[e[i].b]++] = e[i].a;
    }
    for (i = 0; i < n; i++) {
        double d = rest_sd[i] - attachment;
        radius[i] = d > 0 ? (d < max_distance ? d : max_distance) : 0.0;
    }
    free(e);
    free(fill);
    if (scl_tethers(rest, n, nptr, nidx, radius, anchor, tether) < 0) return -1;
    return ne;
}

/* ---- per frame ------------------------------------------------------------------------------------------ */
/* The per-sweep stiffness that gives k after `sweeps` sweeps: 1 - (1 - k)^(1/sweeps), by bisection with
 * products only (no pow: every platform and JavaScript give the same bits). */
SCL_API double scl_per_sweep(double k, int64_t sweeps) {
    double lo = 0.0, hi = 1.0;
    int s;
    int64_t j;
    if (!(k > 0)) return 0.0;
    if (k >= 1 || sweeps <= 1) return k >= 1 ? 1.0 : k;
    for (s = 0; s < 64; s++) {
        double mid = 0.5 * (lo + hi), q = 1.0;
        for (j = 0; j < sweeps; j++) q *= 1.0 - mid;
        if (1.0 - q < k) lo = mid; else hi = mid;
    }
    return 0.5 * (lo + hi);
}

static int all_finite(const double *a, int64_t n) {
    /* a[i] - a[i] is 0, or NaN for NaN and inf; four sums of them (no branch per element, independent adds) */
    double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    int64_t i;
    for (i = 0; i + 4 <= n; i += 4) {
        s0 += a[i] - a[i];
        s1 += a[i + 1] - a[i + 1];
        s2 += a[i + 2] - a[i + 2];
        s3 += a[i + 3] - a[i + 3];
    }
    for (; i < n; i++) s0 += a[i] - a[i];
    return s0 + s1 + s2 + s3 == 0;
}

/* Keep x within r of y (r = 0: x = y). */
static void attach(double *x, const double *y, double r) {
    double e0 = x[0] - y[0], e1 = x[1] - y[1], e2 = x[2] - y[2], l2 = e0 * e0 + e1 * e1 + e2 * e2;
    if (l2 > r * r) {
        double s = r > 0 ? r / sqrt(l2) : 0.0;
        x[0] = y[0] + s * e0;
        x[1] = y[1] + s * e1;
        x[2] = y[2] + s * e2;
    }
}

/* An edge with a free end, as the sweeps read it (scl_step packs them once per call, in edge order, leaving out
 * the edges whose ends are both attached, which no sweep moves): its ends, their weights (1 free, 0 attached), its
 * limits hi = hi_f L0 and lo = lo_f L0 and their squares.  One memory read per edge instead of five. */
typedef struct {
    int64_t a, b;
    double wa, wb, hi, lo, hi2, lo2;
} scl_pedge;

/* One edge's strain limit: move the free ends of edge pe along it (Provot 1995 with PBD's stiffness k). */
static void stretch_edge(double *x, const scl_pedge *pe, double k) {
    double *p = x + 3 * pe->a, *q = x + 3 * pe->b, d0, d1, d2, l2, len, c, s, wa = pe->wa, wb = pe->wb;
    d0 = q[0] - p[0];
    d1 = q[1] - p[1];
    d2 = q[2] - p[2];
    l2 = d0 * d0 + d1 * d1 + d2 * d2;
    if (l2 <= pe->hi2 && l2 >= pe->lo2) return; /* within the limits (most edges): no square root */
    len = sqrt(l2);
    if (len < SCL_TINY) return; /* no direction: left to the other constraints */
    c = l2 > pe->hi2 ? len - pe->hi : len - pe->lo; /* the side decided as above (the root may round onto hi) */
    s = k * c / (len * (wa + wb));
    p[0] += wa * s * d0;
    p[1] += wa * s * d1;
    p[2] += wa * s * d2;
    q[0] -= wb * s * d0;
    q[1] -= wb * s * d1;
    q[2] -= wb * s * d2;
}

/* Whether vertex i at x may be inside the body or closer than the margin: found so or in contact (sd, its signed
 * distance where the contacts were found, at xc, within margin + band), or farther from xc than its clearance (that
 * distance less the margin, at most the band: a vertex nearer xc is on the same side of the skin as there, and
 * outside the margin if it was outside the band). */
static int may_be_near(const double *x, const double *xc, const double *sd, int64_t i, double margin, double band) {
    double d0 = x[3 * i] - xc[3 * i], d1 = x[3 * i + 1] - xc[3 * i + 1], d2 = x[3 * i + 2] - xc[3 * i + 2];
    double clear = (sd[i] < margin + band ? sd[i] : margin + band) - margin;
    return !(clear > 0) || sd[i] < margin + band || d0 * d0 + d1 * d1 + d2 * d2 >= clear * clear;
}

/* Vertex i appended to the push-out's list: its index to pick, its position to q, its flag in moved cleared. */
static void pick_vertex(const double *x, int64_t i, double *q, int64_t *pick, uint8_t *moved, int64_t *m) {
    pick[*m] = i;
    q[3 * *m] = x[3 * i];
    q[3 * *m + 1] = x[3 * i + 1];
    q[3 * *m + 2] = x[3 * i + 2];
    moved[*m] = 0;
    (*m)++;
}

/* The attachment in the settling after the push-out: x kept within r of its target y, or within the distance from y
 * at which the sweeps and the push-out left it (x0) if that is farther -- a contact's move (an edge lifted off a
 * ridge, a vertex pushed out) is not undone. */
static void settle_attach(double *x, const double *y, const double *x0, double r) {
    double e0 = x[0] - y[0], e1 = x[1] - y[1], e2 = x[2] - y[2], l2 = e0 * e0 + e1 * e1 + e2 * e2;
    double f0 = x0[0] - y[0], f1 = x0[1] - y[1], f2 = x0[2] - y[2], m2 = f0 * f0 + f1 * f1 + f2 * f2, s;
    if (l2 <= r * r || l2 <= m2) return;
    s = (r * r >= m2 ? r : sqrt(m2)) / sqrt(l2);
    x[0] = y[0] + s * e0;
    x[1] = y[1] + s * e1;
    x[2] = y[2] + s * e2;
}

/* One edge's strain limit in the settling after the push-out: an end the push-out moved (held) does not move. */
static void settle_edge(double *x, const scl_pedge *pe, const uint8_t *held, double k) {
    scl_pedge p = *pe;
    if (held[p.a]) p.wa = 0;
    if (held[p.b]) p.wb = 0;
    if (p.wa + p.wb > 0) stretch_edge(x, &p, k);
}

/* One free vertex's tether: pulled toward its anchor (attached: never moved by edges, smoothing or tethers) when
 * farther from it than hi_f times the tether's rest length. */
static void tether_vertex(double *x, const int64_t *anchor, const double *tether, int64_t i, double hi_f, double k) {
    int64_t a = anchor[i];
    double *p = x + 3 * i, *o, d0, d1, d2, l2, lim, s;
    if (a < 0) return;
    o = x + 3 * a;
    lim = hi_f * tether[i];
    d0 = p[0] - o[0];
    d1 = p[1] - o[1];
    d2 = p[2] - o[2];
    l2 = d0 * d0 + d1 * d1 + d2 * d2;
    if (l2 <= lim * lim) return; /* within (most vertices): no square root */
    s = k * (1.0 - lim / sqrt(l2));
    p[0] -= s * d0;
    p[1] -= s * d1;
    p[2] -= s * d2;
}

/* One vertex's smoothing: its deviation from the target moved toward its neighbours' mean deviation. */
static void smooth_vertex(double *x, const double *y, const int64_t *nptr, const int64_t *nidx, const double *radius,
                          int64_t i, double k) {
    int64_t j, deg = nptr[i + 1] - nptr[i];
    double m0 = 0, m1 = 0, m2 = 0;
    if (deg == 0 || !(radius[i] > 0)) return;
    for (j = nptr[i]; j < nptr[i + 1]; j++) {
        int64_t v = nidx[j];
        m0 += x[3 * v] - y[3 * v];
        m1 += x[3 * v + 1] - y[3 * v + 1];
        m2 += x[3 * v + 2] - y[3 * v + 2];
    }
    m0 /= (double)deg;
    m1 /= (double)deg;
    m2 /= (double)deg;
    x[3 * i] += k * (m0 - (x[3 * i] - y[3 * i]));
    x[3 * i + 1] += k * (m1 - (x[3 * i + 1] - y[3 * i + 1]));
    x[3 * i + 2] += k * (m2 - (x[3 * i + 2] - y[3 * i + 2]));
}

/* Whether edge e gets a contact plane at its middle: an end in contact (sd within `near`) and an end free. */
static double dot3(const double *u, const double *v) { return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]; }

/* Whether edge e gets a contact plane at its middle: an end in contact (sd within `near`) and an end free; or both
 * ends attached, both in contact, on the same side of the body (their contact normals cn within SCL_AGREE), where
 * the body may bulge between them into the edge's middle: the sag of a ridge whose sides have those normals, under
 * the edge's chord of length l, (l / 2) tan(phi / 2) with cos(phi) = na . nb, more than the room the ends leave
 * (their mean distance over the margin) plus a quarter of the margin.  A flat stretch of skin (phi ~ 0) asks for no
 * query: on a tight garment that is most of its edges. */
static int edge_near(const int64_t *edges, int64_t e, const double *x, const double *sd, const double *cn,
                     const double *radius, double margin, double near) {
    int64_t a = edges[2 * e], b = edges[2 * e + 1];
    double c, d0, d1, d2, room;
    if (radius[a] > 0 || radius[b] > 0) return sd[a] < near || sd[b] < near;
    if (!(sd[a] < near && sd[b] < near)) return 0;
    c = dot3(cn + 3 * a, cn + 3 * b);
    if (!(c > SCL_AGREE)) return 0;
    d0 = x[3 * b] - x[3 * a];
    d1 = x[3 * b + 1] - x[3 * a + 1];
    d2 = x[3 * b + 2] - x[3 * a + 2];
    room = 0.5 * ((sd[a] > margin ? sd[a] : margin) + (sd[b] > margin ? sd[b] : margin)) - margin + 0.25 * margin;
    return 0.25 * (d0 * d0 + d1 * d1 + d2 * d2) * (1.0 - c) > room * room * (1.0 + c);
}

/* Whether the middle's contact normal n agrees with both ends' (an edge with both ends attached keeps its middle's
 * plane only then: a middle whose closest point is on another body part, an arm against the torso, is left alone). */
static int edge_agrees(const int64_t *edges, int64_t e, const double *cn, const double *radius, const double *n) {
    int64_t a = edges[2 * e], b = edges[2 * e + 1];
    if (radius[a] > 0 || radius[b] > 0) return 1;
    return dot3(n, cn + 3 * a) > SCL_AGREE && dot3(n, cn + 3 * b) > SCL_AGREE;
}

/* One edge's contact: both ends of edge e moved alike along the plane's normal n until the edge's middle is margin
 * outside the plane through c (when the middle was found within margin + band of the body and not deeper inside than
 * SCL_EDGE_DEEP: sd).  A middle deeper inside is not a contact but a limb through the cloth (or cloth in a pinch),
 * whose closest surface may be on either side of it from one frame to the next: its plane moved both ends by up to
 * 7 cm, one frame and not the next -- 300 of the 360 vertex-frames that popped on a T-shirt in a dance (issue #26,
 * eighth session).  Its ends' own contacts and the push-out take them out. */
static void edge_contact(double *x, const int64_t *edges, int64_t e, double sd, const double *c, const double *nrm,
                         double margin, double band) {
    double *p = x + 3 * edges[2 * e], *q = x + 3 * edges[2 * e + 1], s;
    if (!(sd < margin + band) || sd < -SCL_EDGE_DEEP) return;
    s = nrm[0] * (0.5 * (p[0] + q[0]) - c[0]) + nrm[1] * (0.5 * (p[1] + q[1]) - c[1]) +
        nrm[2] * (0.5 * (p[2] + q[2]) - c[2]) - margin;
    if (s < 0) {
        p[0] -= s * nrm[0];
        p[1] -= s * nrm[1];
        p[2] -= s * nrm[2];
        q[0] -= s * nrm[0];
        q[1] -= s * nrm[1];
        q[2] -= s * nrm[2];
    }
}

/* The backstop's buffers (scl_step allocates them once per call). */
typedef struct {
    double *vn, *d, *d2, *yt, *pts, *g, *tsd, *tcp, *tcn;
    int64_t *deep, *region, nr;
    uint8_t *fixed, *held, *done;
    double *dist;
    scl_item *heap;
} scl_work;

/* The backstop's buffers for n vertices with nptr[n] neighbour entries (once per scl_step call, on first need).
 * Returns 0, -1 when out of memory (what was allocated is freed by the caller). */
static int work_alloc(scl_work *w, int64_t n, const int64_t *nptr) {
    w->vn = (double *)malloc(sizeof(double) * 3 * (size_t)n);
    w->d = (double *)malloc(sizeof(double) * 3 * (size_t)n);
    w->d2 = (double *)malloc(sizeof(double) * 3 * (size_t)n);
    w->yt = (double *)malloc(sizeof(double) * 3 * (size_t)n);
    w->pts = (double *)malloc(sizeof(double) * 3 * (size_t)n);
    w->g = (double *)malloc(sizeof(double) * 3 * (size_t)n);
    w->tsd = (double *)malloc(sizeof(double) * (size_t)n);
    w->tcp = (double *)malloc(sizeof(double) * 3 * (size_t)n);
    w->tcn = (double *)malloc(sizeof(double) * 3 * (size_t)n);
    w->deep = (int64_t *)malloc(sizeof(int64_t) * (size_t)n);
    w->region = (int64_t *)malloc(sizeof(int64_t) * (size_t)n);
    w->fixed = (uint8_t *)malloc((size_t)n);
    w->held = (uint8_t *)malloc((size_t)n);
    w->done = (uint8_t *)malloc((size_t)n);
    w->dist = (double *)malloc(sizeof(double) * (size_t)n);
    w->heap = (scl_item *)malloc(sizeof(scl_item) * (size_t)(n + nptr[n]));
    return w->vn && w->d && w->d2 && w->yt && w->pts && w->g && w->tsd && w->tcp && w->tcn && w->deep && w->region &&
                   w->fixed && w->held && w->done && w->dist && w->heap
               ? 0
               : -1;
}

/* The backstop (see the header): when a loose vertex's target y (radius >= SCL_LOOSE) is deeper than `deep` (S_BACKSTOP)
 * inside the body and its prediction x inside (sd, from the frame's contacts with normals cn), the deep targets traced out
 * along the garment's outward normal, the moves spread over the free vertices near them (attached ones keep theirs:
 * 0); yt = y + the spread move and x moved alike.  Returns how many vertices were traced out (0: yt and x are
 * untouched), -1 when out of memory. */
static int64_t backstop(const void *collider, const double *bv, const double *box, int64_t n, int64_t nf,
                        const int64_t *faces, const int64_t *weld, const int64_t *nptr, const int64_t *nidx, const double *radius,
                        const double *y, double *x, const double *sd, const double *cn, double margin, double band,
                        double deep, scl_work *w) {
    int64_t i, j, k, nd = 0, nt = 0;
    double vote = 0, sign;
    if (!(deep > 0)) return 0; /* off */
    for (i = 0; i < n; i++) nd += radius[i] >= SCL_LOOSE;
    if (nd == 0) return 0;
    if (!w->vn && work_alloc(w, n, nptr) < 0) return -1;
    /* the loose vertices whose target is deeper than `deep` inside: the network's depth, not the prediction's (which
     * follows the output of the frame before: deep one frame, traced out, shallow the next, left to its closest exit
     * on the other side of the limb -- a jacket's panel in a hip flipped front to back every other frame) */
    nd = 0;
    for (i = 0; i < n; i++)
        if (radius[i] >= SCL_LOOSE) {
            w->deep[nd] = i;
            w->pts[3 * nd] = y[3 * i];
            w->pts[3 * nd + 1] = y[3 * i + 1];
            w->pts[3 * nd + 2] = y[3 * i + 2];
            nd++;
        }
    sdc_near(collider, bv, box, w->pts, 0, nd, 0.0, w->tsd, w->tcp, w->tcn, 0);
    k = nd;
    nd = 0;
    for (j = 0; j < k; j++)
        if (w->tsd[j] < -deep && sd[w->deep[j]] < 0) w->deep[nd++] = w->deep[j];
    if (nd == 0) return 0;
    /* the target's vertex normals (area-weighted face normals) and their orientation: outward where the vertices
     * just outside the body agree with the body's normal */
    for (i = 0; i < 3 * n; i++) w->vn[i] = 0;
    for (j = 0; j < nf; j++) {
        const int64_t a = weld[faces[3 * j]], b = weld[faces[3 * j + 1]], c = weld[faces[3 * j + 2]];
        const double *pa = y + 3 * a, *pb = y + 3 * b, *pc = y + 3 * c;
        double u0 = pb[0] - pa[0], u1 = pb[1] - pa[1], u2 = pb[2] - pa[2];
        double v0 = pc[0] - pa[0], v1 = pc[1] - pa[1], v2 = pc[2] - pa[2];
        double f0 = u1 * v2 - u2 * v1, f1 = u2 * v0 - u0 * v2, f2 = u0 * v1 - u1 * v0;
        const int64_t abc[3] = {a, b, c};
        for (k = 0; k < 3; k++) {
            w->vn[3 * abc[k]] += f0;
            w->vn[3 * abc[k] + 1] += f1;
            w->vn[3 * abc[k] + 2] += f2;
        }
    }
    for (i = 0; i < n; i++)
        if (sd[i] >= 0 && sd[i] < margin + band)
            vote += w->vn[3 * i] * cn[3 * i] + w->vn[3 * i + 1] * cn[3 * i + 1] + w->vn[3 * i + 2] * cn[3 * i + 2];
    sign = vote < 0 ? -1.0 : 1.0;
    /* sphere-trace each deep target along its unit outward normal */
    for (j = 0; j < nd; j++) {
        const double *q = w->vn + 3 * w->deep[j];
        double l2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2], s = l2 > SCL_TINY ? sign / sqrt(l2) : 0.0;
        w->g[3 * j] = s * q[0];
        w->g[3 * j + 1] = s * q[1];
        w->g[3 * j + 2] = s * q[2];
        w->pts[3 * j] = y[3 * w->deep[j]];
        w->pts[3 * j + 1] = y[3 * w->deep[j] + 1];
        w->pts[3 * j + 2] = y[3 * w->deep[j] + 2];
        w->fixed[j] = 0; /* 1 once traced out of the body */
    }
    for (k = 0; k < SCL_TRACE; k++) {
        int64_t left = 0;
        sdc_near(collider, bv, box, w->pts, 0, nd, margin, w->tsd, w->tcp, w->tcn, 1);
        for (j = 0; j < nd; j++) {
            double step;
            if (w->fixed[j]) continue;
            if (w->tsd[j] >= margin) {
                w->fixed[j] = 1;
                continue;
            }
            step = margin - w->tsd[j] + SCL_OVERSHOOT;
            w->pts[3 * j] += step * w->g[3 * j];
            w->pts[3 * j + 1] += step * w->g[3 * j + 1];
            w->pts[3 * j + 2] += step * w->g[3 * j + 2];
            left++;
        }
        if (left == 0) break;
    }
    if (k == SCL_TRACE) { /* the last step's points: out or not */
        sdc_near(collider, bv, box, w->pts, 0, nd, margin, w->tsd, w->tcp, w->tcn, 1);
        for (j = 0; j < nd; j++)
            if (w->tsd[j] >= margin) w->fixed[j] = 1;
    }
    /* a trace longer than SCL_REACH went through the torso rather than out of a limb (a jacket's panel in the torso,
     * traced 37 cm out of the back: a pop each frame it was traced and not the next): dropped, its vertex left to its
     * contacts and the push-out */
    for (j = 0; j < nd; j++) {
        const double *t = w->pts + 3 * j, *o = y + 3 * w->deep[j];
        double e0 = t[0] - o[0], e1 = t[1] - o[1], e2 = t[2] - o[2];
        if (w->fixed[j] && e0 * e0 + e1 * e1 + e2 * e2 > SCL_REACH * SCL_REACH) w->fixed[j] = 0;
    }
    /* the moves of the traced-out ones (with a normal), held; spread to the others */
    for (i = 0; i < 3 * n; i++) w->d[i] = 0;
    for (i = 0; i < n; i++) w->held[i] = 0;
    for (j = 0; j < nd; j++) {
        if (!w->fixed[j] || (w->g[3 * j] == 0 && w->g[3 * j + 1] == 0 && w->g[3 * j + 2] == 0)) continue;
        i = w->deep[j];
        w->d[3 * i] = w->pts[3 * j] - y[3 * i];
        w->d[3 * i + 1] = w->pts[3 * j + 1] - y[3 * i + 1];
        w->d[3 * i + 2] = w->pts[3 * j + 2] - y[3 * i + 2];
        w->held[i] = 1;
        nt++;
    }
    if (nt == 0) return 0;
    /* the region the moves spread over: the vertices within SCL_SPREAD_RADIUS of a held one along the target's
     * edges (Dijkstra from every held vertex at once); outside it the move is 0 */
    {
        int64_t len = 0;
        for (i = 0; i < n; i++) {
            w->dist[i] = w->held[i] ? 0.0 : INFINITY;
            w->done[i] = 0;
            if (w->held[i]) heap_push(w->heap, &len, 0.0, i);
        }
        w->nr = 0;
        while (len > 0) {
            scl_item it = heap_pop(w->heap, &len);
            int64_t v = it.v;
            if (w->done[v] || it.d > w->dist[v]) continue;
            w->done[v] = 1;
            if (!w->held[v] && radius[v] > 0 && nptr[v + 1] > nptr[v]) w->region[w->nr++] = v;
            for (j = nptr[v]; j < nptr[v + 1]; j++) {
                int64_t u = nidx[j];
                double e0 = y[3 * u] - y[3 * v], e1 = y[3 * u + 1] - y[3 * v + 1], e2 = y[3 * u + 2] - y[3 * v + 2];
                double c = it.d + sqrt(e0 * e0 + e1 * e1 + e2 * e2);
                if (w->done[u] || !(c <= SCL_SPREAD_RADIUS) || !(c < w->dist[u])) continue;
                w->dist[u] = c;
                heap_push(w->heap, &len, c, u);
            }
        }
    }
    /* Jacobi sweeps over the region: each move the mean of its neighbours' (held ones and those outside fixed) */
    for (k = 0; k < SCL_SPREAD; k++) {
        int64_t r;
        for (r = 0; r < w->nr; r++) {
            int64_t deg;
            double m0 = 0, m1 = 0, m2 = 0;
            i = w->region[r];
            deg = nptr[i + 1] - nptr[i];
            for (j = nptr[i]; j < nptr[i + 1]; j++) {
                m0 += w->d[3 * nidx[j]];
                m1 += w->d[3 * nidx[j] + 1];
                m2 += w->d[3 * nidx[j] + 2];
            }
            w->d2[3 * r] = m0 / (double)deg;
            w->d2[3 * r + 1] = m1 / (double)deg;
            w->d2[3 * r + 2] = m2 / (double)deg;
        }
        for (r = 0; r < w->nr; r++) {
            i = w->region[r];
            w->d[3 * i] = w->d2[3 * r];
            w->d[3 * i + 1] = w->d2[3 * r + 1];
            w->d[3 * i + 2] = w->d2[3 * r + 2];
        }
    }
    for (i = 0; i < 3 * n; i++) {
        w->yt[i] = y[i] + w->d[i];
        x[i] += w->d[i];
    }
    return nt;
}

/* The cloth stage on nb frames: targets (B, N, 3) -> out (B, N, 3), against the posed body (B, V, 3) through the
 * collider (sdc_create on the body's faces), with the per-garment data of scl_setup (edges to tether), the
 * garment's faces (nf, 3) (the backstop's normals, through scl_setup's weld; their indices checked by scl_setup) and
 * settings (S_COUNT,).
 * state (3, N, 3): the last output, the one before it and the last target; info (I_COUNT,): I_HAVE how many of
 * the state's frames are set (0: none, the next frame starts from its target), counts added to (I_RESETS,
 * I_CONTACTS: vertex-frames with a contact plane, I_PUSHED: vertex-frames the final push-out moved by more than
 * SCL_MOVED, I_TRACED: vertex-frames whose deep target the backstop traced out), and
 * I_FIRST_RESET set to the first frame of this call that reset the state (-1: none).
 * Returns 0; -1 when out of memory; 1 + f for the first frame f whose target or body holds NaN or inf: every frame
 * is checked before any is stepped, so then no frame is done and the state and the counts are as they were. */
SCL_API int64_t scl_step(int64_t n, int64_t ne, const int64_t *edges, const double *rest_len, const int64_t *nptr,
                         const int64_t *nidx, const double *radius, const int64_t *anchor, const double *tether,
                         const int64_t *weld, int64_t nf, const int64_t *faces, const double *settings, const void *collider,
                         int64_t nv, const double *body, int64_t nb, const double *target, double *out, double *state,
                         int64_t *info) {
    int64_t iters = (int64_t)settings[S_ITERATIONS], n_nodes = sdc_n_nodes(collider), f, i, it, e;
    double ks = scl_per_sweep(settings[S_STIFFNESS], iters), kb = scl_per_sweep(settings[S_BENDING], iters);
    double hi_f = 1.0 + settings[S_STRETCH], lo_f = 1.0 - settings[S_COMPRESS];
    double keep = 1.0 - settings[S_DAMPING], drop = settings[S_GRAVITY] * settings[S_DT] * settings[S_DT];
    double margin = settings[S_MARGIN], reset = settings[S_RESET], band = SCL_CONTACT_BAND;
    double follow = settings[S_FOLLOW];
    double *x1 = state, *x0 = state + 3 * n, *yp = state + 6 * n;
    double *box = (double *)malloc(sizeof(double) * 6 * (size_t)n_nodes);
    double *sd = (double *)malloc(sizeof(double) * (size_t)n);
    double *cp = (double *)malloc(sizeof(double) * 3 * (size_t)n);
    double *cn = (double *)malloc(sizeof(double) * 3 * (size_t)n);
    double *q = (double *)malloc(sizeof(double) * 3 * (size_t)n);
    double *xc = (double *)malloc(sizeof(double) * 3 * (size_t)n); /* the positions the contacts were found at */
    int64_t *pick = (int64_t *)malloc(sizeof(int64_t) * (size_t)n);
    /* what the sweeps visit, in their order: the edges with a free end (pe), the free vertices with neighbours (fv:
     * smoothing) and those with a tether (tv); the constraints they leave out would move nothing */
    scl_pedge *pe = (scl_pedge *)malloc(sizeof(scl_pedge) * (size_t)(ne > 0 ? ne : 1));
    int64_t *fv = (int64_t *)malloc(sizeof(int64_t) * (size_t)n), *tv = (int64_t *)malloc(sizeof(int64_t) * (size_t)n);
    int64_t npe = 0, nfv = 0, ntv = 0;
    uint8_t *moved = (uint8_t *)malloc((size_t)n);
    uint8_t *held = (uint8_t *)malloc((size_t)n); /* moved by this frame's final push-out: held by the settling */
    /* the edge contacts' buffers, grown to the most edges near the body in one frame (not sized by every edge:
     * memory stays O(vertices + contacts)) */
    int64_t *eidx = NULL, nec, cap = 0;
    double *mid = NULL, *esd = NULL, *ecp = NULL, *ecn = NULL;
    scl_work w;
    int64_t status = 0;
    memset(&w, 0, sizeof(w)); /* the backstop's buffers: allocated when a frame first needs them */
    if (iters < 1) iters = 1;
    info[I_FIRST_RESET] = -1;
    if (!box || !sd || !cp || !cn || !q || !xc || !pick || !moved || !held || !pe || !fv || !tv) {
        status = -1;
        goto done;
    }
    for (e = 0; e < ne; e++) {
        int64_t a = edges[2 * e], b = edges[2 * e + 1];
        double wa = radius[a] > 0 ? 1.0 : 0.0, wb = radius[b] > 0 ? 1.0 : 0.0;
        if (wa + wb == 0) continue;
        pe[npe].a = a;
        pe[npe].b = b;
        pe[npe].wa = wa;
        pe[npe].wb = wb;
        pe[npe].hi = hi_f * rest_len[e];
        pe[npe].lo = lo_f * rest_len[e];
        pe[npe].hi2 = pe[npe].hi * pe[npe].hi;
        pe[npe].lo2 = pe[npe].lo * pe[npe].lo;
        npe++;
    }
    for (i = 0; i < n; i++) {
        if (nptr[i + 1] > nptr[i] && radius[i] > 0) fv[nfv++] = i;
        if (anchor[i] >= 0) tv[ntv++] = i;
    }
    /* every frame checked before any is stepped: a frame with NaN or inf leaves the state and the counts as they were */
    for (f = 0; f < nb; f++)
        if (!all_finite(target + 3 * n * f, 3 * n) || !all_finite(body + 3 * nv * f, 3 * nv)) {
            status = 1 + f;
            goto done;
        }
    for (f = 0; f < nb; f++) {
        const double *y = target + 3 * n * f, *bv = body + 3 * nv * f, *yc = y;
        double *x = out + 3 * n * f;
        int64_t have = info[I_HAVE], m, nt, npushed;
        if (have > 0) { /* a teleport: the target moved more than `reset` on average */
            double s = 0;
            for (i = 0; i < n; i++) {
                double d0 = y[3 * i] - yp[3 * i], d1 = y[3 * i + 1] - yp[3 * i + 1], d2 = y[3 * i + 2] - yp[3 * i + 2];
                s += sqrt(d0 * d0 + d1 * d1 + d2 * d2);
            }
            if (!(s / (double)n <= reset)) {
                have = 0;
                info[I_RESETS]++;
                if (info[I_FIRST_RESET] < 0) info[I_FIRST_RESET] = f;
            }
        }
        /* predict: inertia and gravity from the previous outputs, within the attachment */
        for (i = 0; i < n; i++) {
            double *p = x + 3 * i;
            if (have == 0) {
                p[0] = y[3 * i];
                p[1] = y[3 * i + 1];
                p[2] = y[3 * i + 2];
            } else {
                double v0 = 0, v1 = 0, v2 = 0;
                if (have >= 2) {
                    v0 = x1[3 * i] - x0[3 * i];
                    v1 = x1[3 * i + 1] - x0[3 * i + 1];
                    v2 = x1[3 * i + 2] - x0[3 * i + 2];
                }
                p[0] = x1[3 * i] + keep * v0;
                p[1] = x1[3 * i + 1] + keep * v1 - drop;
                p[2] = x1[3 * i + 2] + keep * v2;
                p[0] += follow * (y[3 * i] - p[0]);
                p[1] += follow * (y[3 * i + 1] - p[1]);
                p[2] += follow * (y[3 * i + 2] - p[2]);
            }
            attach(p, y + 3 * i, radius[i]);
        }
        /* contacts: a plane for every vertex inside the body or near it */
        sdc_refit(collider, bv, box);
        sdc_near(collider, bv, box, x, 0, n, margin + band, sd, cp, cn, 0);
        /* deep targets: traced out along the garment's normal (the backstop), then the contacts found again */
        nt = backstop(collider, bv, box, n, nf, faces, weld, nptr, nidx, radius, y, x, sd, cn, margin, band,
                      settings[S_BACKSTOP], &w);
        if (nt < 0) { status = -1; goto done; }
        if (nt > 0) { /* only the vertices it moved (held and in the region) are looked up again */
            int64_t r, nm = 0;
            info[I_TRACED] += nt;
            yc = w.yt;
            for (i = 0; i < n; i++)
                if (w.held[i]) w.deep[nm++] = i;
            for (r = 0; r < w.nr; r++) w.deep[nm++] = w.region[r];
            for (r = 0; r < nm; r++) {
                w.pts[3 * r] = x[3 * w.deep[r]];
                w.pts[3 * r + 1] = x[3 * w.deep[r] + 1];
                w.pts[3 * r + 2] = x[3 * w.deep[r] + 2];
            }
            sdc_near(collider, bv, box, w.pts, 0, nm, margin + band, w.tsd, w.tcp, w.tcn, 0);
            for (r = 0; r < nm; r++) {
                i = w.deep[r];
                sd[i] = w.tsd[r];
                memcpy(cp + 3 * i, w.tcp + 3 * r, sizeof(double) * 3);
                memcpy(cn + 3 * i, w.tcn + 3 * r, sizeof(double) * 3);
            }
        }
        /* and for the middle of every edge with an end in contact and a free end, or both ends attached, in contact
         * and agreeing (edge_near; only those: an edge whose ends are both clear of the body is left unchecked, which
         * keeps the extra queries to the edges near it) */
        nec = 0;
        for (e = 0; e < ne; e++) nec += edge_near(edges, e, x, sd, cn, radius, margin, margin + band);
        if (nec > cap) {
            size_t c = (size_t)nec;
            void *a = realloc(eidx, sizeof(int64_t) * c), *b, *d, *g, *h;
            if (a) eidx = (int64_t *)a;
            b = realloc(mid, sizeof(double) * 3 * c);
            if (b) mid = (double *)b;
            d = realloc(esd, sizeof(double) * c);
            if (d) esd = (double *)d;
            g = realloc(ecp, sizeof(double) * 3 * c);
            if (g) ecp = (double *)g;
            h = realloc(ecn, sizeof(double) * 3 * c);
            if (h) ecn = (double *)h;
            if (!a || !b || !d || !g || !h) { status = -1; goto done; }
            cap = nec;
        }
        nec = 0;
        for (e = 0; e < ne; e++) {
            const double *pa = x + 3 * edges[2 * e], *pb = x + 3 * edges[2 * e + 1];
            if (!edge_near(edges, e, x, sd, cn, radius, margin, margin + band)) continue;
            eidx[nec] = e;
            mid[3 * nec] = 0.5 * (pa[0] + pb[0]);
            mid[3 * nec + 1] = 0.5 * (pa[1] + pb[1]);
            mid[3 * nec + 2] = 0.5 * (pa[2] + pb[2]);
            nec++;
        }
        if (nec > 0) sdc_near(collider, bv, box, mid, 0, nec, margin + band, esd, ecp, ecn, 0);
        for (e = 0; e < nec; e++)
            if (!edge_agrees(edges, eidx[e], cn, radius, ecn + 3 * e)) esd[e] = INFINITY;
        memcpy(xc, x, sizeof(double) * 3 * (size_t)n);
        /* the sweeps, alternating direction */
        for (it = 0; it < iters; it++) {
            int fwd = it % 2 == 0;
            for (e = 0; e < npe; e++) stretch_edge(x, pe + (fwd ? e : npe - 1 - e), ks);
            if (ks > 0)
                for (i = 0; i < ntv; i++) tether_vertex(x, anchor, tether, tv[i], hi_f, ks);
            if (kb > 0)
                for (i = 0; i < nfv; i++) smooth_vertex(x, yc, nptr, nidx, radius, fv[fwd ? i : nfv - 1 - i], kb);
            for (i = 0; i < n; i++) {
                double *p = x + 3 * i, s;
                attach(p, yc + 3 * i, radius[i]);
                if (!(sd[i] < margin + band)) continue;
                s = cn[3 * i] * (p[0] - cp[3 * i]) + cn[3 * i + 1] * (p[1] - cp[3 * i + 1]) +
                    cn[3 * i + 2] * (p[2] - cp[3 * i + 2]) - margin;
                if (s < 0) {
                    p[0] -= s * cn[3 * i];
                    p[1] -= s * cn[3 * i + 1];
                    p[2] -= s * cn[3 * i + 2];
                }
            }
            for (e = 0; e < nec; e++) edge_contact(x, edges, eidx[e], esd[e], ecp + 3 * e, ecn + 3 * e, margin, band);
        }
        /* the exact push-out of every vertex that may be inside or closer than the margin: those found inside or
         * within it, those in contact (within the band: one of them may be inside the torso by a buried arm's
         * skin, which only the push-out's rule for buried skin tells), and those that moved farther than their
         * clearance (the distance from the body less the margin, at least the band for vertices not found) since
         * the contacts were found */
        m = 0;
        for (i = 0; i < n; i++) {
            info[I_CONTACTS] += sd[i] < margin + band;
            if (may_be_near(x, xc, sd, i, margin, band)) pick_vertex(x, i, q, pick, moved, &m);
        }
        npushed = 0;
        for (i = 0; i < n; i++) held[i] = 0;
        if (m > 0) {
            sdc_push_out(collider, bv, box, 1, q, m, 0, m, margin, SCL_PASSES, moved);
            for (i = 0; i < m; i++) {
                double *p = x + 3 * pick[i], d0 = q[3 * i] - p[0], d1 = q[3 * i + 1] - p[1], d2 = q[3 * i + 2] - p[2];
                held[pick[i]] = d0 * d0 + d1 * d1 + d2 * d2 > SCL_MOVED * SCL_MOVED;
                npushed += held[pick[i]];
                p[0] = q[3 * i];
                p[1] = q[3 * i + 1];
                p[2] = q[3 * i + 2];
            }
            info[I_PUSHED] += npushed;
        }
        /* settling: when the push-out moved a vertex, the sweeps' stretch limits and attachment again (no contact
         * planes) with the vertices it moved held where it put them, so that their free neighbours follow them
         * instead of leaving the edges between them stretched; the vertices these sweeps moved that may now be inside
         * or within the margin -- by the final push-out's test: in contact, or farther than their clearance from
         * where the contacts were found (a vertex nearer that place is on the same side of the skin as it was
         * there) -- are pushed out again */
        if (npushed > 0) {
            memcpy(q, x, sizeof(double) * 3 * (size_t)n);
            for (it = 0; it < iters; it++) {
                int fwd = it % 2 == 0;
                for (e = 0; e < npe; e++) settle_edge(x, pe + (fwd ? e : npe - 1 - e), held, ks);
                for (i = 0; i < n; i++)
                    if (!held[i] && radius[i] > 0) settle_attach(x + 3 * i, yc + 3 * i, q + 3 * i, radius[i]);
            }
            m = 0;
            for (i = 0; i < n; i++) {
                double d0 = x[3 * i] - q[3 * i], d1 = x[3 * i + 1] - q[3 * i + 1], d2 = x[3 * i + 2] - q[3 * i + 2];
                if (d0 * d0 + d1 * d1 + d2 * d2 > 0 && may_be_near(x, xc, sd, i, margin, band))
                    pick_vertex(x, i, q, pick, moved, &m);
            }
            if (m > 0) {
                sdc_push_out(collider, bv, box, 1, q, m, 0, m, margin, SCL_PASSES, moved);
                for (i = 0; i < m; i++) memcpy(x + 3 * pick[i], q + 3 * i, sizeof(double) * 3);
            }
        }
        /* a seam's sides: every vertex where its group's lowest one is (scl_setup's weld) */
        for (i = 0; i < n; i++)
            if (weld[i] != i) memcpy(x + 3 * i, x + 3 * weld[i], sizeof(double) * 3);
        /* the state: this frame, the one before, this target */
        if (have == 0) memcpy(x0, x, sizeof(double) * 3 * (size_t)n);
        else memcpy(x0, x1, sizeof(double) * 3 * (size_t)n);
        memcpy(x1, x, sizeof(double) * 3 * (size_t)n);
        memcpy(yp, y, sizeof(double) * 3 * (size_t)n);
        info[I_HAVE] = have == 0 ? 1 : 2;
    }
done:
    free(pe); free(fv); free(tv);
    free(box); free(sd); free(cp); free(cn); free(q); free(xc); free(pick); free(moved); free(held);
    free(eidx); free(mid); free(esd); free(ecp); free(ecn);
    free(w.vn); free(w.d); free(w.d2); free(w.yt); free(w.pts); free(w.g); free(w.tsd); free(w.tcp); free(w.tcn);
    free(w.deep); free(w.fixed); free(w.held); free(w.done); free(w.region); free(w.dist); free(w.heap);
    return status;
}

/* ---- the Python extension module ------------------------------------------------------------------------ */
/* Built (with _collide.c) as the empty module segadeform.body._cloth so that setuptools compiles it at install;
 * the functions above are reached through ctypes.  Other builds leave SCL_PYTHON_MODULE undefined. */
#ifdef SCL_PYTHON_MODULE
static struct PyModuleDef scl_module = {PyModuleDef_HEAD_INIT, "_cloth",
                                        "segadeform's compiled cloth stage (called through ctypes).", -1, NULL, NULL,
                                        NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__cloth(void) { return PyModule_Create(&scl_module); }
#endif
