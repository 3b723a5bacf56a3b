/* modscope's optional compiled core: the loops that run once a byte, a packet or a row.
 *
 *  - bulk_epbs: walks the blocks of a piece of a pcapng file while they are data packets
 *    (link type 250 data records, link type 147 packets) of one batch
 *    (sniffer/sources/pcap.py: _bulk_blocks);
 *  - bulk_pcap: the same over the records of a classic pcap file (_bulk_pcap_records);
 *  - rtu_scan: the RTU framer's fast paths 1 and 2 with the read-by-read timeline step
 *    (sniffer/framing/serial.py: RtuFramer._scan_bytes, _Timeline.add_read);
 *  - pair_rows, pair_update: pairing (sniffer/framing/store.py: FrameStore.pair_rows,
 *    sniffer/framing/pairing.py: Pairer.update);
 *  - stats_scan, ranked: the per-unit statistics and their nearest-rank quantiles
 *    (sniffer/analysis/stats.py: Stats.update, nearest_rank, median_gap);
 *  - sunspec_rows, mask_rows: the first tests of SunSpecTracker.follow_rows, and the rows
 *    of the annotator's mask it is handed (sniffer/meaning/sunspec.py: follow_mask);
 *  - join_reads: batches of reads held by the pipeline, as one (sniffer/framing/pipeline.py);
 *  - poll_table, poll_block: the poll cycle's requests, keyed and grouped by the same-poll
 *    rule Python hands over (sniffer/analysis/pollcycle.py: PollCycles.add; the rule:
 *    sniffer/analysis/polls.py);
 *  - waits_count, waits_densify: the poll cycle's waits between sendings, counted in
 *    buckets, and counted again in buckets from zero (sniffer/analysis/pollcycle.py:
 *    _Waits.count, _Waits.densify);
 *  - tally_latencies, tally_gaps: the bounded statistics' counts of printed figures
 *    (sniffer/analysis/stats.py: Tallies.add_latencies, Tallies.add_requests);
 *  - export_table, export_rows: the pcapng export's packet blocks of the rows whose
 *    content it has a template for (sniffer/outputs/export.py: PcapExporter.write, _rows);
 *  - listing_table, listing_rows: the text and JSONL listings' lines of the rows whose
 *    content it has the parts of (sniffer/outputs/listing.py: Lister.write);
 *  - shift_partners, bounds: a sidecar block's partners renumbered, and the least and
 *    greatest word of a column its checks take (sniffer/session/index.py:
 *    shifted_partners, _bounds);
 *  - constants: the product's numbers this file says itself, which
 *    tests/core/test_core_constants.py holds to the Python that defines them.
 *
 * All are copies of the Python code named, which stays the reference and the fallback:
 * each stops where that code would do anything else and hands the position back, so the
 * Python code takes over from exactly there. Float results are computed with the same
 * operations in the same order (the build turns off fused multiply-add) so they are
 * bit-identical. sniffer/core.py says which core runs.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

/* ---- growable byte buffers, returned as bytes -------------------------------------- */

typedef struct {
    char *p;
    Py_ssize_t n, cap;
} Buf;

static int buf_grow(Buf *b, Py_ssize_t n) {
    Py_ssize_t cap = b->cap ? b->cap : 256;
    while (cap < b->n + n) cap *= 2;
    char *p = PyMem_Realloc(b->p, (size_t)cap);
    if (p == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    b->p = p;
    b->cap = cap;
    return 0;
}

/* Room for at least `n` bytes in all (an empty buffer's first allocation, sized to what
 * the caller expects to put): spares the doublings and their copies. */
static int buf_reserve(Buf *b, Py_ssize_t n) {
    if (n <= b->cap) return 0;
    char *p = PyMem_Realloc(b->p, (size_t)n);
    if (p == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    b->p = p;
    b->cap = n;
    return 0;
}

/* Inlined where it is called, so that the copy of a value of a size known there (an
 * 8-byte time or offset) is a move, not a call to memcpy: it runs for every column of
 * every packet and row. */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline int buf_put(Buf *b, const void *src, Py_ssize_t n) {
    if (b->n + n > b->cap && buf_grow(b, n) < 0) return -1;
    memcpy(b->p + b->n, src, (size_t)n);
    b->n += n;
    return 0;
}

static PyObject *buf_bytes(Buf *b) {
    return PyBytes_FromStringAndSize(b->p ? b->p : "", b->n);
}

static void buf_free(Buf *b) {
    PyMem_Free(b->p);
    b->p = NULL;
    b->n = b->cap = 0;
}

/* ---- CRC-16/MODBUS, table-driven ---------------------------------------------------- */

static uint16_t crc_table[256];
/* crc_slices[k][b]: the register after byte b then k zero bytes, from a zero register
 * (crc_slices[0] is crc_table): the scan's check takes four bytes a step (crc16_4) */
static uint16_t crc_slices[4][256];

static void crc_init(void) {
    for (int i = 0; i < 256; i++) {
        uint16_t c = (uint16_t)i;
        for (int j = 0; j < 8; j++) c = (c & 1) ? (uint16_t)((c >> 1) ^ 0xA001) : (uint16_t)(c >> 1);
        crc_table[i] = c;
    }
    for (int i = 0; i < 256; i++) {
        crc_slices[0][i] = crc_table[i];
        for (int k = 1; k < 4; k++) {
            uint16_t c = crc_slices[k - 1][i];
            crc_slices[k][i] = (uint16_t)((c >> 8) ^ crc_table[c & 0xFF]);
        }
    }
}

static uint16_t crc16(const unsigned char *p, Py_ssize_t n) {
    uint16_t crc = 0xFFFF;
    for (Py_ssize_t i = 0; i < n; i++) crc = (uint16_t)((crc >> 8) ^ crc_table[(crc ^ p[i]) & 0xFF]);
    return crc;
}

/* crc16, four bytes a step: the same register (the framer's hot check; a frame's CRC is
 * its dearest per-byte work). Two register bytes and two data bytes go through the four
 * tables at once, so the steps do not wait on each other byte by byte. */
static inline uint16_t crc16_4(const unsigned char *p, Py_ssize_t n) {
    uint32_t crc = 0xFFFF;
    Py_ssize_t i = 0;
    for (; i + 4 <= n; i += 4) {
        crc ^= (uint32_t)p[i] | (uint32_t)p[i + 1] << 8;
        crc = (uint32_t)crc_slices[3][crc & 0xFF] ^ crc_slices[2][crc >> 8] ^
              crc_slices[1][p[i + 2]] ^ crc_slices[0][p[i + 3]];
    }
    for (; i < n; i++) crc = (crc >> 8) ^ crc_table[(crc ^ p[i]) & 0xFF];
    return (uint16_t)crc;
}

static PyObject *py_crc16(PyObject *self, PyObject *arg) {
    Py_buffer v;
    if (PyObject_GetBuffer(arg, &v, PyBUF_SIMPLE) < 0) return NULL;
    uint16_t c = crc16((const unsigned char *)v.buf, v.len);
    PyBuffer_Release(&v);
    return PyLong_FromLong(c);
}

/* ---- the product's numbers, where C must say them ------------------------------------ */

/* Each is Python's too (sniffer/vocab.py, the registry of dissectors/pdu, the sources'
 * limits): constants() says them all back, and tests/core/test_core_constants.py holds
 * each to the Python it restates, so neither can change alone. */

/* what a row is, what became of its transaction, and the flags the passes test or set
 * (sniffer/vocab.py: Kind, Status, Flag, BAD_CHECK) */
#define K_NOISE 0
#define K_REQUEST 1
#define K_RESPONSE 2
#define K_EXCEPTION 3
#define K_UNKNOWN 4
#define K_EVENT 5
#define S_OK 1
#define S_EXCEPTION 2
#define S_TIMEOUT 3
#define S_ORPHAN 4
#define S_BROADCAST 5
#define S_OPEN 6
#define S_BAD_ANSWER 7
#define F_CHECK_BAD (1u << 0)
#define F_NON_HEX (1u << 4)
#define F_ENVELOPE_BAD (1u << 17)
#define F_ASCII (1u << 24)
#define F_MBAP (1u << 25)
#define BAD_CHECK_BITS (F_CHECK_BAD | F_NON_HEX | F_ENVELOPE_BAD)
#define F_RETRY (1u << 11)
#define F_LATE (1u << 12)
#define F_ANSWERED_BROADCAST (1u << 13)

/* the bit an answer's function code carries when it is an exception */
#define EXCEPTION_BIT 0x80

/* The function codes whose layouts the export's packet keys read (the registry's
 * families and tables: dissectors/pdu/bits.py, registers.py), and the lengths of their
 * RTU requests (unit, PDU, CRC). SunSpec's first look is given its own at each call. */
#define FC_READ(c) ((c) >= 1 && (c) <= 4)             /* family "read" */
#define FC_READ_BITS(c) ((c) == 1 || (c) == 2)        /* ... of coils or discrete inputs */
#define FC_READ_REGISTERS(c) ((c) == 3 || (c) == 4)   /* ... of registers */
#define FC_WRITE_SINGLE(c) ((c) == 5 || (c) == 6)     /* family "write_single" */
#define FC_WRITE_COIL(c) ((c) == 5)                   /* ... of a coil */
#define FC_WRITE_MULTIPLE(c) ((c) == 15 || (c) == 16) /* family "write_multiple" */
#define FC_WRITE_COILS(c) ((c) == 15)                 /* ... of coils */
#define TABLE_REQUEST_LENGTH 8 /* a read's or single write's request (its fixed length) */
#define MULTIPLE_COUNT_AT 6    /* a multiple write's byte count: where it is, */
#define MULTIPLE_BASE 9        /* and the request's length less the bytes it counts */
#define READ_ANSWER_BASE 5     /* a read's answer's length less the bytes it counts */

/* ---- pcapng: runs of data packets (link type 250 data records, link type 147) ---------- */

#define BLOCK_EPB 6u
#define MAX_BLOCK (1u << 26)
#define RTAC_HEADER_LEN 12
#define RTAC_DATA_RX_START 2
#define EPB_FLAGS 2
#define MAX_TIME 1e10
#define RTAC_MAX_LEAD 60.0
#define MAX_BATCH_SPAN 4.0
#define MAX_BATCH_BYTES (1 << 19)

static uint32_t rd32(const unsigned char *p, int big) {
    if (big) return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
    return (uint32_t)p[3] << 24 | (uint32_t)p[2] << 16 | (uint32_t)p[1] << 8 | p[0];
}

static uint16_t rd16(const unsigned char *p, int big) {
    return big ? (uint16_t)(p[0] << 8 | p[1]) : (uint16_t)(p[1] << 8 | p[0]);
}

/* ticks / tps rounded to nearest, ties to even, as Python's int / int; 0 when this
 * cannot say (the quotient is below 1 or has more than 53 bits): the caller declines. */
static int exact_quotient(uint64_t ticks, uint64_t tps, double *out) {
    uint64_t q = ticks / tps, r = ticks % tps;
    if (q == 0 || q >> 53) return 0;
#ifdef __GNUC__
    int bits = 64 - __builtin_clzll(q);
#else
    int bits = 0;
    for (uint64_t v = q; v; v >>= 1) bits++;
#endif
    int s = 53 - bits;
    uint64_t m;
    if (s == 0 || r >> (64 - s) == 0) {
        /* the s bits of the fraction in one 64-bit division, the cheapest: r << s fits
         * for the usual stamps (nanoseconds of this century: r < 2**30, s = 22) */
        uint64_t frac = r << s;
        m = q << s | frac / tps;
        r = frac % tps;
    } else {
#ifdef __SIZEOF_INT128__
        /* as the loop below computes them, in one division rather than a step a bit */
        unsigned __int128 frac = (unsigned __int128)r << s;
        m = q << s | (uint64_t)(frac / tps);
        r = (uint64_t)(frac % tps);
#else
        m = q;
        for (int i = 0; i < s; i++) {
            r <<= 1; /* r < tps <= 2**62 */
            m <<= 1;
            if (r >= tps) {
                r -= tps;
                m |= 1;
            }
        }
#endif
    }
    uint64_t r2 = r << 1;
    if (r2 > tps || (r2 == tps && (m & 1))) m += 1;
    *out = ldexp((double)m, -s);
    return 1;
}

typedef struct {
    int ok;
    uint64_t tps;
    double offset;
    int role;
    uint32_t skip; /* bytes of header before the bytes read: 12 for RTAC records, 0 USER0 */
} Iface;

/* bulk_epbs(buf, pos, limit, big, ifaces, b_index, b_dir, b_bytes, b_first)
 *   -> (pos, cut, b_index, b_dir, b_bytes, b_first, data, ends, t_starts, t_ends)
 * Takes data records from `pos` while _bulk_blocks would take them into the batch
 * described by b_index (-1: none open), b_dir, b_bytes, b_first. `limit` is the file's
 * size less the file offset of buf[0]. `ifaces` holds, per interface index of the
 * section, None or (ticks per second, offset seconds, role, header length: 12 for link
 * type 250, whose RTAC header is read, 0 for 147). Stops at the first block
 * the Python walk must look at; `cut` says the batch must be passed on before the
 * record at `pos`. ends are int64, times float64 (NaN: no start time), native order. */
static PyObject *py_bulk_epbs(PyObject *self, PyObject *args) {
    Py_buffer view;
    Py_ssize_t pos, limit, b_index, b_dir, b_bytes;
    int big;
    PyObject *ifaces_obj;
    double b_first;
    if (!PyArg_ParseTuple(args, "y*nnpOnnnd", &view, &pos, &limit, &big, &ifaces_obj, &b_index,
                          &b_dir, &b_bytes, &b_first))
        return NULL;
    const unsigned char *buf = (const unsigned char *)view.buf;
    Py_ssize_t len = view.len;
    Iface *ifaces = NULL;
    Py_ssize_t n_ifaces = 0;
    Buf data = {0}, ends = {0}, starts = {0}, tends = {0};
    PyObject *result = NULL;
    int cut = 0;

    if (!PyList_Check(ifaces_obj)) {
        PyErr_SetString(PyExc_TypeError, "ifaces must be a list");
        goto done;
    }
    n_ifaces = PyList_GET_SIZE(ifaces_obj);
    ifaces = PyMem_Calloc((size_t)(n_ifaces ? n_ifaces : 1), sizeof(Iface));
    if (ifaces == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t i = 0; i < n_ifaces; i++) {
        PyObject *item = PyList_GET_ITEM(ifaces_obj, i);
        if (item == Py_None) continue;
        unsigned long long tps;
        long long offset;
        int role, skip;
        if (!PyArg_ParseTuple(item, "KLii", &tps, &offset, &role, &skip)) goto done;
        if (skip != 0 && skip != RTAC_HEADER_LEN) {
            PyErr_SetString(PyExc_ValueError, "header length must be 0 or 12");
            goto done;
        }
        ifaces[i].ok = 1;
        ifaces[i].tps = tps;
        ifaces[i].offset = (double)offset; /* |offset| < 2**53: exact, as Python converts */
        ifaces[i].role = role;
        ifaces[i].skip = (uint32_t)skip;
    }

    for (;;) {
        if (pos + 12 > len) break;
        const unsigned char *b = buf + pos;
        uint32_t type = rd32(b, big), total = rd32(b + 4, big);
        if (type != BLOCK_EPB) break;
        if (total < 36 || total % 4 || total > MAX_BLOCK || pos + (Py_ssize_t)total > limit ||
            pos + (Py_ssize_t)total > len)
            break;
        if (rd32(b + total - 4, big) != total) break;
        uint32_t index = rd32(b + 8, big);
        uint64_t ticks = (uint64_t)rd32(b + 12, big) << 32 | rd32(b + 16, big);
        uint32_t caplen = rd32(b + 20, big);
        if (index >= (uint64_t)n_ifaces || !ifaces[index].ok) break;
        Iface *iface = &ifaces[index];
        uint64_t tail = 28 + (uint64_t)caplen + ((4 - caplen % 4) % 4);
        uint64_t stop = total - 4;
        if (caplen <= iface->skip || tail > stop) break;
        uint32_t flags = 0;
        if (tail != stop) {
            const unsigned char *o = b + tail;
            if (stop - tail != 12 || rd16(o, big) != EPB_FLAGS || rd16(o + 2, big) != 4 || o[8] ||
                o[9] || o[10] || o[11])
                break;
            flags = rd32(o + 4, big);
        }
        const unsigned char *rec = b + 28;
        uint32_t secs = 0, usecs = 0;
        if (iface->skip) {
            secs = rd32(rec, 1);
            usecs = rd32(rec + 4, 1);
            if (rec[8] != RTAC_DATA_RX_START) break;
        }
        double t;
        if (!exact_quotient(ticks, iface->tps, &t)) break;
        t = t + iface->offset;
        if (!(0.0 <= t && t < MAX_TIME)) break;
        int direction = iface->role ? iface->role : ((flags & 3) == 2 ? 1 : 0);
        if (b_index >= 0 && ((Py_ssize_t)index != b_index || direction != b_dir ||
                             t - b_first > MAX_BATCH_SPAN || b_bytes > MAX_BATCH_BYTES)) {
            cut = 1;
            break;
        }
        if (b_index < 0) {
            b_index = index;
            b_dir = direction;
            b_bytes = 0;
            b_first = t;
        }
        double t_start = Py_NAN;
        if (iface->skip) {
            double seconds = (double)secs + (double)usecs / 1e6;
            double lead = t - seconds;
            if (0.0 < lead && lead < RTAC_MAX_LEAD) t_start = seconds;
        }
        int64_t end;
        b_bytes += caplen - iface->skip;
        end = b_bytes;
        if (buf_put(&data, rec + iface->skip, caplen - iface->skip) < 0 ||
            buf_put(&ends, &end, 8) < 0 || buf_put(&starts, &t_start, 8) < 0 ||
            buf_put(&tends, &t, 8) < 0)
            goto done;
        pos += total;
    }
    {
        PyObject *d = buf_bytes(&data), *e = buf_bytes(&ends), *s = buf_bytes(&starts),
                 *te = buf_bytes(&tends);
        if (d && e && s && te)
            result = Py_BuildValue("(nOnnndOOOO)", pos, cut ? Py_True : Py_False, b_index, b_dir,
                                   b_bytes, b_first, d, e, s, te);
        Py_XDECREF(d);
        Py_XDECREF(e);
        Py_XDECREF(s);
        Py_XDECREF(te);
    }
done:
    PyMem_Free(ifaces);
    buf_free(&data);
    buf_free(&ends);
    buf_free(&starts);
    buf_free(&tends);
    PyBuffer_Release(&view);
    return result;
}

/* bulk_pcap(buf, pos, limit, big, header, skip, tps, b_open, b_bytes, b_first)
 *   -> (pos, cut, b_open, b_bytes, b_first, data, ends, t_starts, t_ends)
 * The records of a classic pcap file from `pos` while _bulk_pcap_records would take them
 * into the batch described by b_open, b_bytes, b_first: `header` is the record header's
 * length (16, or 24 for the "modified" format), `skip` that of the payload's header (12:
 * link type 250, whose RTAC header is read; 0: link type 147), `tps` 10**6 or 10**9.
 * `limit` as for bulk_epbs. The packet time is secs + frac / tps, both exact doubles, so
 * one rounding each as Python's int + int / int. */
static PyObject *py_bulk_pcap(PyObject *self, PyObject *args) {
    Py_buffer view;
    Py_ssize_t pos, limit, header, skip, b_bytes;
    unsigned long long tps;
    int big, b_open;
    double b_first;
    if (!PyArg_ParseTuple(args, "y*nnpnnKpnd", &view, &pos, &limit, &big, &header, &skip, &tps,
                          &b_open, &b_bytes, &b_first))
        return NULL;
    const unsigned char *buf = (const unsigned char *)view.buf;
    Py_ssize_t len = view.len;
    Buf data = {0}, ends = {0}, starts = {0}, tends = {0};
    PyObject *result = NULL;
    int cut = 0;
    if ((header != 16 && header != 24) || (skip != 0 && skip != RTAC_HEADER_LEN) || tps == 0 ||
        tps > (1ull << 53) || pos < 0) {
        PyErr_SetString(PyExc_ValueError, "bulk_pcap: bad record layout");
        goto done;
    }
    for (;;) {
        if (pos + header > len) break;
        const unsigned char *b = buf + pos;
        uint32_t secs = rd32(b, big), frac = rd32(b + 4, big), length = rd32(b + 8, big);
        if (length > MAX_BLOCK || pos + header + (Py_ssize_t)length > limit ||
            pos + header + (Py_ssize_t)length > len)
            break;
        if (length <= (uint32_t)skip) break;
        double t = (double)secs + (double)frac / (double)tps;
        if (!(0.0 <= t && t < MAX_TIME)) break;
        const unsigned char *rec = b + header;
        double t_start = Py_NAN;
        if (skip) {
            if (rec[8] != RTAC_DATA_RX_START) break;
            double seconds = (double)rd32(rec, 1) + (double)rd32(rec + 4, 1) / 1e6;
            double lead = t - seconds;
            if (0.0 < lead && lead < RTAC_MAX_LEAD) t_start = seconds;
        }
        if (b_open && (t - b_first > MAX_BATCH_SPAN || b_bytes > MAX_BATCH_BYTES)) {
            cut = 1;
            break;
        }
        if (!b_open) {
            b_open = 1;
            b_bytes = 0;
            b_first = t;
        }
        int64_t end;
        b_bytes += length - skip;
        end = b_bytes;
        if (buf_put(&data, rec + skip, length - skip) < 0 || buf_put(&ends, &end, 8) < 0 ||
            buf_put(&starts, &t_start, 8) < 0 || buf_put(&tends, &t, 8) < 0)
            goto done;
        pos += header + length;
    }
    {
        PyObject *d = buf_bytes(&data), *e = buf_bytes(&ends), *s = buf_bytes(&starts),
                 *te = buf_bytes(&tends);
        if (d && e && s && te)
            result = Py_BuildValue("(nOOndOOOO)", pos, cut ? Py_True : Py_False,
                                   b_open ? Py_True : Py_False, b_bytes, b_first, d, e, s, te);
        Py_XDECREF(d);
        Py_XDECREF(e);
        Py_XDECREF(s);
        Py_XDECREF(te);
    }
done:
    buf_free(&data);
    buf_free(&ends);
    buf_free(&starts);
    buf_free(&tends);
    PyBuffer_Release(&view);
    return result;
}

/* ---- the RTU framer's fast paths ------------------------------------------------------ */

#define MIN_RTU 4
#define MAX_RTU 256
#define EXCEPTION_LENGTH 5
#define FIXED (-1) /* AnswerRule.FIXED */
#define ECHO (-2)  /* AnswerRule.ECHO */
#define WALKED (-3)

typedef struct {
    Py_ssize_t start, end;
    double t_start, t_end, gap;
} Span;

/* The span of the reads holding `pos`, as _Timeline._span finds it (the newest whose
 * first byte is at or before pos): among the reads added by this call, then the read that
 * was the newest when it began (`entry`); NULL when pos lies before those. */
static const Span *span_at(const Span *entry, const Span *spans, Py_ssize_t n, Py_ssize_t pos) {
    for (Py_ssize_t j = n - 1; j >= 0; j--)
        if (spans[j].start <= pos) return &spans[j];
    if (entry == NULL) return NULL;
    if (entry[0].start <= pos) return &entry[0];
    /* the read holding the scan's first position, when older than the newest read */
    return entry[1].end > entry[1].start && entry[1].start <= pos && pos < entry[1].end ? &entry[1]
                                                                                        : NULL;
}

/* _Timeline.start_time and end_time of one span, with Python's operations in its order */
static double span_start(const Span *s, Py_ssize_t pos) {
    Py_ssize_t n = s->end - s->start;
    return n ? s->t_start + (double)(pos - s->start) * (s->t_end - s->t_start) / (double)n
             : s->t_start;
}

static double span_end(const Span *s, Py_ssize_t pos) {
    Py_ssize_t n = s->end - s->start;
    return n ? s->t_start + (double)(pos + 1 - s->start) * (s->t_end - s->t_start) / (double)n
             : s->t_end;
}

static Py_ssize_t floordiv(Py_ssize_t a, Py_ssize_t b) {
    Py_ssize_t q = a / b;
    if ((a % b != 0) && ((a < 0) != (b < 0))) q -= 1;
    return q;
}

/* The length of the answer a request of `length` bytes at `frame` asks for
 * (RtuLengths.predict), from the rule table's answer columns; -1 when its rule predicts
 * none or the request is too short to hold the quantity the rule reads. */
static inline Py_ssize_t predict_answer(const int64_t *tab, const unsigned char *frame,
                                        Py_ssize_t length, Py_ssize_t fc) {
    const int64_t *answer_pos = tab + 512, *answer_base = tab + 768, *answer_item = tab + 1024,
                  *answer_up = tab + 1280, *answer_byte = tab + 1536;
    Py_ssize_t ap = answer_pos[fc];
    if (ap >= 0) {
        if (length < ap + 2) return -1;
        Py_ssize_t q = frame[ap] << 8 | frame[ap + 1];
        return (Py_ssize_t)answer_base[fc] +
               floordiv(q * (Py_ssize_t)answer_item[fc] + (Py_ssize_t)answer_up[fc],
                        (Py_ssize_t)answer_byte[fc]);
    }
    if (ap == FIXED) return (Py_ssize_t)answer_base[fc];
    if (ap == ECHO) return length;
    return -1;
}

/* What the slow path's search finds at pos (RtuLengths.candidates, then, when it finds
 * nothing and waits for nothing, RtuLengths.silence_framed), never at the end of the
 * bytes (final): a frame (its length and kind), nothing (the byte is noise), a wait for
 * more bytes, or "unsure" where the compiled copy does not know all Python knows (a
 * length rule with a walker, a read older than those it was given, a frame only silence
 * frames): the slow path decides those. */
enum { SEARCH_NONE, SEARCH_FOUND, SEARCH_WAIT, SEARCH_UNSURE };

/* the timeline as rtu_scan knows it: its reads (see span_at) and the silences before
 * them (_Timeline.boundaries as it was given, a sorted list of ints, then its own reads'
 * gaps, all of them after those) */
typedef struct {
    const Span *entry, *spans;
    Py_ssize_t n_spans;
    PyObject *bounds;
    double t35;
} Times;

/* the index of the first boundary given after pos (`after`), or at or after it */
static Py_ssize_t times_bisect(PyObject *bounds, Py_ssize_t pos, int after) {
    Py_ssize_t lo = 0, hi = PyList_GET_SIZE(bounds);
    while (lo < hi) {
        Py_ssize_t mid = (lo + hi) / 2;
        Py_ssize_t b = PyLong_AsSsize_t(PyList_GET_ITEM(bounds, mid));
        if (after ? b <= pos : b < pos)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* _Timeline.is_boundary */
static int times_boundary(const Times *tm, Py_ssize_t pos) {
    Py_ssize_t i = times_bisect(tm->bounds, pos, 0);
    if (i < PyList_GET_SIZE(tm->bounds))
        return PyLong_AsSsize_t(PyList_GET_ITEM(tm->bounds, i)) == pos;
    for (Py_ssize_t j = tm->n_spans - 1; j >= 0 && tm->spans[j].start >= pos; j--)
        if (tm->spans[j].start == pos && tm->spans[j].gap >= tm->t35) return 1;
    return 0;
}

/* _Timeline.next_boundary: -1 for None */
static Py_ssize_t times_next_boundary(const Times *tm, Py_ssize_t pos) {
    Py_ssize_t i = times_bisect(tm->bounds, pos, 1);
    if (i < PyList_GET_SIZE(tm->bounds)) return PyLong_AsSsize_t(PyList_GET_ITEM(tm->bounds, i));
    Py_ssize_t next = -1;
    for (Py_ssize_t j = tm->n_spans - 1; j >= 0 && tm->spans[j].start > pos; j--)
        if (tm->spans[j].gap >= tm->t35) next = tm->spans[j].start;
    return next;
}

/* The times of the frame from pos to stop, as the fast paths give them: from the newest
 * read's rate when the frame begins in that read (the inline estimate); else, a frame begun
 * in an earlier read, as _Timeline.start_time and end_time give them, from the spans of the
 * reads holding its first and last bytes (as the search times what it finds). 0 when one of
 * those reads is not among those known here (see span_at). */
static inline int frame_times(const Span *entry, const Span *spans, Py_ssize_t n_spans,
                              Py_ssize_t cur_start, double cur_t0, double cur_rate,
                              Py_ssize_t pos, Py_ssize_t stop, double *t0, double *t1) {
    if (pos >= cur_start) {
        *t0 = cur_t0 + (double)(pos - cur_start) * cur_rate;
        *t1 = *t0 + (double)(stop - pos) * cur_rate;
        return 1;
    }
    const Span *s0 = span_at(entry, spans, n_spans, pos);
    const Span *s1 = span_at(entry, spans, n_spans, stop - 1);
    if (s0 == NULL || s1 == NULL) return 0;
    *t0 = span_start(s0, pos);
    *t1 = span_end(s1, stop - 1);
    return 1;
}

/* What an echo of the request at p (code fc) must repeat of it, as lengths.echo_key: how
 * many bytes (ECHO_REPEATS) above their value; -1 where the code says nothing. */
#define KEY_BITS 48
static Py_ssize_t echo_key(const unsigned char *p, Py_ssize_t avail, int fc) {
    int n = (fc == 5 || fc == 6 || fc == 21 || fc == 22) ? 6 : fc == 8 ? 4 : 0;
    if (!n || avail < n) return -1;
    int64_t v = 0;
    for (int i = 0; i < n; i++) v = v << 8 | p[i];
    return (Py_ssize_t)((int64_t)n << KEY_BITS | v);
}

/* lengths.not_its_echo: the frame at pos does not repeat what `key` names (0 while its
 * bytes are not all below end, or key names nothing) */
static int not_its_echo(const unsigned char *buf, Py_ssize_t pos, Py_ssize_t end,
                        Py_ssize_t key) {
    if (key < 0) return 0;
    int n = (int)((int64_t)key >> KEY_BITS);
    if (pos + n > end) return 0;
    int64_t v = 0;
    for (int i = 0; i < n; i++) v = v << 8 | buf[pos + i];
    return v != ((int64_t)key & (((int64_t)1 << KEY_BITS) - 1));
}

/* `rules`: RtuLengths.rule_bytes, the length rules of each code (compile_rules), two
 * slots of (kind, base, count_pos, count_size) int64; kind 0: no rule, -1: a rule this
 * copy cannot follow (a walker). */
static int rtu_search(const unsigned char *buf, Py_ssize_t pos, Py_ssize_t end,
                      const int64_t *rules, const int64_t *answer_pos, Py_ssize_t pu,
                      Py_ssize_t pf, Py_ssize_t pl, double pdl, double band, Py_ssize_t pe,
                      const Times *tm, Py_ssize_t *found, int *kind) {
    int unit = buf[pos], fc = buf[pos + 1];
    Py_ssize_t len[3];
    int prio[3], knd[3], n = 0, waiting = 0;
    if (unit == pu && (fc & 0x7F) == pf) { /* the answer the open request predicts */
        int live = 1;
        if (!(fc & EXCEPTION_BIT) && pdl != Py_HUGE_VAL) { /* RtuLengths._expired */
            const Span *s = span_at(tm->entry, tm->spans, tm->n_spans, pos);
            if (s == NULL) return SEARCH_UNSURE;
            double t0 = span_start(s, pos);
            live = !(t0 > pdl || (t0 > pdl - band && not_its_echo(buf, pos, end, pe)));
        }
        if (live) {
            if (fc & EXCEPTION_BIT) {
                len[n] = EXCEPTION_LENGTH, prio[n] = 0, knd[n++] = K_EXCEPTION;
            } else {
                int agrees = answer_pos[fc] < 0 || buf[pos + 2] == pl - 5;
                len[n] = pl, prio[n] = agrees ? 0 : 3, knd[n++] = K_RESPONSE;
            }
        }
    }
    for (int r = 0; r < 2; r++) {
        const int64_t *rule = rules + ((Py_ssize_t)fc * 2 + r) * 4;
        if (rule[0] == 0) continue;
        if (rule[0] < 0) return SEARCH_UNSURE;
        Py_ssize_t length = (Py_ssize_t)rule[1];
        if (rule[3]) {
            Py_ssize_t cp = pos + (Py_ssize_t)rule[2];
            if (cp + rule[3] > end) { /* NEED_MORE */
                waiting = 1;
                continue;
            }
            length += rule[3] == 1 ? buf[cp] : (buf[cp] << 8 | buf[cp + 1]);
        }
        if (length >= MIN_RTU && length <= MAX_RTU) {
            len[n] = length;
            prio[n] = rule[0] == K_REQUEST ? 1 : 2; /* lengths.PREFERENCE */
            knd[n++] = (int)rule[0];
        }
    }
    /* sorted as Python sorts the tuples (length, preference, kind) */
    for (int i = 1; i < n; i++)
        for (int j = i; j > 0; j--) {
            int after = len[j - 1] != len[j]     ? len[j - 1] > len[j]
                        : prio[j - 1] != prio[j] ? prio[j - 1] > prio[j]
                                                 : knd[j - 1] > knd[j];
            if (!after) break;
            Py_ssize_t tl = len[j];
            int tp = prio[j], tk = knd[j];
            len[j] = len[j - 1], prio[j] = prio[j - 1], knd[j] = knd[j - 1];
            len[j - 1] = tl, prio[j - 1] = tp, knd[j - 1] = tk;
        }
    for (int i = 0; i < n; i++) {
        if (pos + len[i] > end) return SEARCH_WAIT;
        if (crc16_4(buf + pos, len[i]) != 0) continue;
        Py_ssize_t length = len[i], best_len = len[i];
        int best_prio = prio[i], best_kind = knd[i];
        if (prio[i])
            for (int j = i + 1; j < n; j++) { /* lengths._preferred */
                if (prio[j] >= best_prio || len[j] == length) continue;
                if (pos + len[j] > end) return SEARCH_WAIT;
                if (crc16_4(buf + pos, len[j]) == 0)
                    best_len = len[j], best_prio = prio[j], best_kind = knd[j];
            }
        *found = best_len;
        *kind = best_kind;
        return SEARCH_FOUND;
    }
    if (waiting) return SEARCH_WAIT;
    /* RtuLengths.silence_framed */
    if (!times_boundary(tm, pos)) return SEARCH_NONE;
    Py_ssize_t next = times_next_boundary(tm, pos);
    if (next < 0) return end - pos <= MAX_RTU ? SEARCH_WAIT : SEARCH_NONE;
    Py_ssize_t length = next - pos;
    if (length >= MIN_RTU && length <= MAX_RTU && crc16_4(buf + pos, length) == 0)
        return SEARCH_UNSURE; /* a frame silence frames: the slow path's */
    return SEARCH_NONE;
}

/* rtu_scan(buf, tables, pos, end, final, batch, pu, pf, pl, pdl, pr, row, timeout,
 *          cur_start, cur_t0, cur_rate, offset, last_end, slack, char_time, t35,
 *          too_fast, first_too_fast, ends, t_starts, t_ends, k, prev, base, split,
 *          held_start, held_end, held_t0, held_t1, rules, noise, boundaries,
 *          noise_start, pe, band)
 * See _compiled_scan (serial.py), which calls it and applies what it returns. NaN stands for
 * None in last_end, first_too_fast and t_starts.
 *
 * With `split`, the fast paths take a frame begun in an earlier read too (pos < cur_start;
 * 16 ms reads of a slow line cut about one frame in three), timed as the search times
 * what it finds (frame_times) and paired as it is framed, as serial.py's fast paths do.
 *
 * With `split` and `noise` (and not `final`), where the fast paths cannot decide, the
 * slow path's search is made here (rtu_search, given `rules` and the timeline's
 * boundaries, a list it only reads). That is where a frame no open request predicts
 * and whose rule the fast paths do not know is framed (an answer after the wait, a
 * walked length, a check that fails at the predicted length),
 * and stray bytes: bytes it finds no frame at are noise (a span under way is returned
 * as noise_start, which the framer keeps and gives back), and the frame found after them
 * is framed as _emit_noise and _emit_frame frame them: the noise row (kind, unit and
 * code 0, no flags, while it is shorter than a frame: a longer one needs the units seen)
 * and the frame's row, timed by the spans of the reads holding their first and last
 * bytes (_Timeline.start_time, end_time: the reads this call adds, the newest read
 * before it, and `held`, the read holding pos when the call began, if older; a frame
 * begun in any other read goes the slow way), left unpaired (RtuFramer._emit_frame
 * leaves slow-path rows to the Pairer), setting the open request. Where the search is
 * unsure it stops for the slow path, the noise under way handed back.
 *
 * A frame begun in an earlier read went to the search before the fast paths took it
 * (the lengths its rules give sorted, each checked): on 5M frames of mix186255415 in
 * 16 ms reads (a third of them split) the scan took 1,707 samples of perf's 8 kHz clock
 * and the Pairer 179 (pairing what the search leaves unpaired), against 1,281 and 86 for
 * the same frames one a packet; with the fast paths taking them, 1,511 and 85. */
static PyObject *py_rtu_scan(PyObject *self, PyObject *args) {
    Py_buffer view, tview, eview, sview, teview;
    Py_ssize_t pos, end, pu, pf, pl, pr, row, cur_start, offset, too_fast, k, prev, base;
    Py_ssize_t noise_start; /* where the noise span under way began (-1: none) */
    int final, batch, split;
    Py_ssize_t held_start, held_end;
    PyObject *old_bounds;
    int noise;
    Py_buffer rview;
    double held_t0, held_t1;
    double pdl, timeout, cur_t0, cur_rate, last_end, slack, char_time, t35, first_too_fast;
    Py_ssize_t pe; /* what the open request's echo repeats of it (echo_key) */
    double band;   /* from how long before pdl only a frame repeating pe is its echo */
    if (!PyArg_ParseTuple(args, "y*y*nnppnnndnndnddnddddndy*y*y*nnnpnnddy*pO!nnd", &view, &tview,
                          &pos, &end, &final, &batch, &pu, &pf, &pl, &pdl, &pr, &row, &timeout,
                          &cur_start, &cur_t0, &cur_rate, &offset, &last_end, &slack, &char_time,
                          &t35, &too_fast, &first_too_fast, &eview, &sview, &teview, &k, &prev,
                          &base, &split, &held_start, &held_end, &held_t0, &held_t1, &rview,
                          &noise, &PyList_Type, &old_bounds, &noise_start, &pe, &band))
        return NULL;
    const int64_t *rules = (const int64_t *)rview.buf;
    Py_ssize_t noise_rows = 0;
    const unsigned char *buf = (const unsigned char *)view.buf;
    const int64_t *tab = (const int64_t *)tview.buf;
    /* the rule table's columns; the answer's, past answer_pos, are read by predict_answer */
    const int64_t *request_base = tab, *request_count = tab + 256, *answer_pos = tab + 512;
    const int64_t *r_ends = (const int64_t *)eview.buf;
    const double *r_starts = (const double *)sview.buf;
    const double *r_tends = (const double *)teview.buf;
    Py_ssize_t count = eview.len / 8;
    Buf c_off = {0}, c_len = {0}, c_t = {0}, c_te = {0}, c_kind = {0}, c_unit = {0}, c_fc = {0};
    Buf c_pairs = {0};
    Span *spans = NULL;
    Py_ssize_t n_spans = 0, k0 = k;
    PyObject *result = NULL;
    int slow = 0;
    const double INF = Py_HUGE_VAL;

    if (tview.len != 7 * 256 * 8 || rview.len != 256 * 2 * 4 * 8) {
        PyErr_SetString(PyExc_ValueError, "tables must be 7 x 256 int64, rules 256 x 8 int64");
        goto done;
    }
    if (batch && count > k) {
        spans = PyMem_Malloc(sizeof(Span) * (size_t)(count - k));
        if (spans == NULL) {
            PyErr_NoMemory();
            goto done;
        }
    }
    {
        /* the row columns sized for a frame every 8 bytes to scan (most are longer;
         * more grow by doubling): spares the doublings and their copies */
        Py_ssize_t last = batch && count > k ? base + (Py_ssize_t)r_ends[count - 1] : end;
        Py_ssize_t rows = last > pos ? (last - pos) / 8 + 16 : 16;
        if (buf_reserve(&c_off, 8 * rows) < 0 || buf_reserve(&c_len, 2 * rows) < 0 ||
            buf_reserve(&c_t, 8 * rows) < 0 || buf_reserve(&c_te, 8 * rows) < 0 ||
            buf_reserve(&c_kind, rows) < 0 || buf_reserve(&c_unit, rows) < 0 ||
            buf_reserve(&c_fc, rows) < 0 || buf_reserve(&c_pairs, 8 * rows) < 0)
            goto done;
    }
    /* the newest read when the call began, for frames that began in it */
    Span entry_spans[2] = {{cur_start, offset, cur_t0, last_end, 0.0},
                           {held_start, held_end, held_t0, held_t1, 0.0}};
    const Span *entry = offset > cur_start && !isnan(last_end) ? entry_spans : NULL;
    Py_ssize_t pfx = pf | EXCEPTION_BIT;
    for (;;) { /* once, or once a read of the batch */
        if (batch) {
            if (k == count) break;
            /* _Timeline.add_read */
            Py_ssize_t read_end = (Py_ssize_t)r_ends[k];
            Py_ssize_t n = read_end - prev;
            double chunk_end = r_tends[k], chunk_start = r_starts[k], t_start;
            Py_ssize_t start = offset;
            if (!isnan(chunk_start)) {
                t_start = chunk_start;
            } else {
                t_start = chunk_end - (double)n * char_time;
                if (!isnan(last_end) && t_start < last_end) {
                    if (t_start < last_end - slack) {
                        too_fast += 1;
                        if (isnan(first_too_fast)) first_too_fast = chunk_end;
                    }
                    t_start = last_end;
                }
            }
            double gap = isnan(last_end) ? INF : t_start - last_end;
            if (t_start > chunk_end) t_start = chunk_end;
            Span *sp = &spans[n_spans++];
            sp->start = start;
            sp->end = start + n;
            sp->t_start = t_start;
            sp->t_end = chunk_end;
            sp->gap = gap;
            cur_start = start;
            cur_t0 = t_start;
            cur_rate = n ? (chunk_end - t_start) / (double)n : 0.0;
            offset += n;
            last_end = chunk_end;
            prev = read_end;
            end = base + read_end;
            k += 1;
        }
        while (end - pos >= MIN_RTU) {
            int unit = buf[pos], fc = buf[pos + 1];
            int inl = noise_start < 0; /* rows framed inline (no noise under way) */
            if (unit == pu && fc == pf && pdl != INF) {
                double t0;
                if (pos >= cur_start) {
                    t0 = cur_t0 + (double)(pos - cur_start) * cur_rate;
                } else { /* the timeline of older reads */
                    const Span *s0 = split ? span_at(entry, spans, n_spans, pos) : NULL;
                    if (s0 == NULL) {
                        slow = 1;
                        goto stopped;
                    }
                    t0 = span_start(s0, pos);
                }
                if (t0 > pdl || (t0 > pdl - band && not_its_echo(buf, pos, end, pe))) pu = -1;
            }
            Py_ssize_t length, stop;
            if (unit == pu && (fc == pf || fc == pfx)) { /* fast path 1 */
                length = fc == pf ? pl : EXCEPTION_LENGTH;
                stop = pos + length;
                if (stop > end) {
                    if (!final) break;
                } else if (inl && (pos >= cur_start || split) &&
                           (fc != pf || answer_pos[pf] < 0 || buf[pos + 2] == pl - 5) &&
                           crc16_4(buf + pos, length) == 0) {
                    double t0, t1;
                    if (!frame_times(entry, spans, n_spans, cur_start, cur_t0, cur_rate, pos,
                                     stop, &t0, &t1)) {
                        slow = 1;
                        goto stopped;
                    }
                    uint64_t o = (uint64_t)pos;
                    uint16_t l = (uint16_t)length;
                    unsigned char kind = fc == pf ? K_RESPONSE : K_EXCEPTION, u = (unsigned char)unit,
                                  f = (unsigned char)fc;
                    if (buf_put(&c_off, &o, 8) < 0 || buf_put(&c_len, &l, 2) < 0 ||
                        buf_put(&c_t, &t0, 8) < 0 || buf_put(&c_te, &t1, 8) < 0 ||
                        buf_put(&c_kind, &kind, 1) < 0 || buf_put(&c_unit, &u, 1) < 0 ||
                        buf_put(&c_fc, &f, 1) < 0)
                        goto done;
                    if (pr >= 0) {
                        int64_t pair[2] = {pr, row};
                        if (buf_put(&c_pairs, pair, 16) < 0) goto done;
                    }
                    pr = pu = -1;
                    row += 1;
                    pos = stop;
                    continue;
                }
            } else if (inl) { /* fast path 2 */
                length = request_base[fc];
                if (length) {
                    Py_ssize_t cpos = request_count[fc];
                    if (cpos) {
                        if (pos + cpos >= end && !final) break;
                        length += pos + cpos < end ? buf[pos + cpos] : 0;
                    }
                    stop = pos + length;
                    if (stop > end) {
                        if (!final) break;
                    } else if ((pos >= cur_start || split) && crc16_4(buf + pos, length) == 0) {
                        Py_ssize_t ap = answer_pos[fc];
                        double t0, t1;
                        if ((unit && ap == WALKED) || /* the answer's length needs Python */
                            !frame_times(entry, spans, n_spans, cur_start, cur_t0, cur_rate, pos,
                                         stop, &t0, &t1)) {
                            slow = 1;
                            goto stopped;
                        }
                        uint64_t o = (uint64_t)pos;
                        uint16_t l = (uint16_t)length;
                        unsigned char kind = K_REQUEST, u = (unsigned char)unit, f = (unsigned char)fc;
                        if (buf_put(&c_off, &o, 8) < 0 || buf_put(&c_len, &l, 2) < 0 ||
                            buf_put(&c_t, &t0, 8) < 0 || buf_put(&c_te, &t1, 8) < 0 ||
                            buf_put(&c_kind, &kind, 1) < 0 || buf_put(&c_unit, &u, 1) < 0 ||
                            buf_put(&c_fc, &f, 1) < 0)
                            goto done;
                        pr = pu = -1;
                        pdl = INF;
                        pe = -1;
                        if (unit) { /* a broadcast gets no answer */
                            pr = row;
                            Py_ssize_t predicted = predict_answer(tab, buf + pos, length, fc);
                            if (predicted >= 0) {
                                pu = unit;
                                pf = fc;
                                pfx = fc | EXCEPTION_BIT;
                                pl = predicted;
                                if (ap == ECHO) { /* from its start, as serial.py */
                                    pdl = t0 +
                                          (double)length *
                                              (pos >= cur_start ? cur_rate : char_time) +
                                          timeout;
                                    pe = echo_key(buf + pos, end - pos, fc);
                                }
                            }
                            if (pl > MAX_RTU) pu = -1;
                        }
                        row += 1;
                        pos = stop;
                        continue;
                    }
                }
            }
            if (!noise || !split || final) {
                slow = 1; /* the slow path decides at pos */
                goto stopped;
            }
            {
                Times tm = {entry, spans, n_spans, old_bounds, t35};
                Py_ssize_t found = 0;
                int fkind = 0;
                int got = rtu_search(buf, pos, end, rules, answer_pos, pu, pf, pl, pdl, band, pe, &tm,
                                     &found, &fkind);
                if (got == SEARCH_WAIT) break;
                if (got == SEARCH_NONE) { /* noise: the search goes on at the next byte */
                    if (noise_start < 0) noise_start = pos;
                    pos += 1;
                    continue;
                }
                /* the frame found, after the noise if any (_emit_noise, _emit_frame) */
                const Span *n0 = NULL, *n1 = NULL, *s0 = NULL, *s1 = NULL;
                if (got == SEARCH_FOUND) {
                    s0 = span_at(entry, spans, n_spans, pos);
                    s1 = span_at(entry, spans, n_spans, pos + found - 1);
                    if (noise_start >= 0) {
                        n0 = span_at(entry, spans, n_spans, noise_start);
                        n1 = span_at(entry, spans, n_spans, pos - 1);
                    }
                }
                Py_ssize_t fc7 = fc & 0x7F, ap = answer_pos[fc7];
                if (got != SEARCH_FOUND || s0 == NULL || s1 == NULL ||
                    (noise_start >= 0 &&
                     (pos - noise_start >= MIN_RTU || n0 == NULL || n1 == NULL)) ||
                    (fkind == K_REQUEST && unit && ap == WALKED)) {
                    slow = 1; /* the slow path decides at pos */
                    goto stopped;
                }
                if (noise_start >= 0) {
                    double t0 = span_start(n0, noise_start), t1 = span_end(n1, pos - 1);
                    uint64_t o = (uint64_t)noise_start;
                    uint16_t l = (uint16_t)(pos - noise_start);
                    unsigned char zero = 0, kind = K_NOISE;
                    if (buf_put(&c_off, &o, 8) < 0 || buf_put(&c_len, &l, 2) < 0 ||
                        buf_put(&c_t, &t0, 8) < 0 || buf_put(&c_te, &t1, 8) < 0 ||
                        buf_put(&c_kind, &kind, 1) < 0 || buf_put(&c_unit, &zero, 1) < 0 ||
                        buf_put(&c_fc, &zero, 1) < 0)
                        goto done;
                    row += 1;
                    noise_rows += 1;
                    noise_start = -1;
                }
                double t0 = span_start(s0, pos), t1 = span_end(s1, pos + found - 1);
                uint64_t o = (uint64_t)pos;
                uint16_t l = (uint16_t)found;
                unsigned char kind = (unsigned char)fkind, u = (unsigned char)unit,
                              f = (unsigned char)fc;
                if (buf_put(&c_off, &o, 8) < 0 || buf_put(&c_len, &l, 2) < 0 ||
                    buf_put(&c_t, &t0, 8) < 0 || buf_put(&c_te, &t1, 8) < 0 ||
                    buf_put(&c_kind, &kind, 1) < 0 || buf_put(&c_unit, &u, 1) < 0 ||
                    buf_put(&c_fc, &f, 1) < 0)
                    goto done;
                pr = -1; /* unpaired: the Pairer pairs it */
                if (fkind == K_REQUEST) {
                    pu = -1;
                    pdl = INF;
                    pe = -1;
                    Py_ssize_t predicted = unit ? predict_answer(tab, buf + pos, found, fc7) : -1;
                    if (predicted >= MIN_RTU && predicted <= MAX_RTU) {
                        pu = unit;
                        pf = fc7;
                        pfx = fc7 | EXCEPTION_BIT;
                        pl = predicted;
                        /* from its start and length, as the fast path (serial.py) */
                        if (ap == ECHO) {
                            pdl = t0 + (double)found * char_time + timeout;
                            pe = echo_key(buf + pos, end - pos, fc7);
                        }
                    }
                } else if (unit == pu) { /* a response or an exception */
                    pu = -1;
                }
                row += 1;
                pos += found;
                continue;
            }
        }
        if (!batch) break;
    }
stopped:;
    /* the reads' spans from the one holding pos on: the timeline forgets what lies
     * before pos (as forget_before does), and nothing asks about it */
    Py_ssize_t first = 0, kept = noise_start >= 0 ? noise_start : pos;
    for (Py_ssize_t j = 0; j < n_spans; j++)
        if (spans[j].start <= kept) first = j;
    /* whether a row other than noise has unit 0 (the framer's units seen: noise has none) */
    int unit0 = 0;
    if (noise_rows)
        for (Py_ssize_t i = 0; i < c_unit.n; i++)
            if (c_unit.p[i] == 0 && c_kind.p[i] != K_NOISE) unit0 = 1;
    PyObject *span_list = PyList_New(0), *bounds = PyList_New(0);
    if (span_list == NULL || bounds == NULL) goto fail_lists;
    for (Py_ssize_t j = first; j < n_spans; j++) {
        Span *sp = &spans[j];
        PyObject *item = Py_BuildValue("(nnddd)", sp->start, sp->end, sp->t_start, sp->t_end,
                                       sp->gap);
        if (item == NULL || PyList_Append(span_list, item) < 0) {
            Py_XDECREF(item);
            goto fail_lists;
        }
        Py_DECREF(item);
        if (sp->gap >= t35) {
            PyObject *b = PyLong_FromSsize_t(sp->start);
            if (b == NULL || PyList_Append(bounds, b) < 0) {
                Py_XDECREF(b);
                goto fail_lists;
            }
            Py_DECREF(b);
        }
    }
    {
        PyObject *cols[8] = {buf_bytes(&c_off),  buf_bytes(&c_len),  buf_bytes(&c_t),
                             buf_bytes(&c_te),   buf_bytes(&c_kind), buf_bytes(&c_unit),
                             buf_bytes(&c_fc),   buf_bytes(&c_pairs)};
        int ok = 1;
        for (int i = 0; i < 8; i++) ok = ok && cols[i] != NULL;
        if (ok)
            result = Py_BuildValue(
                "(OnnnnnnndnnOOOOOOOOnddndndOOnnOn)", slow ? Py_True : Py_False, pos, k, prev, end,
                pu, pf, pl, pdl, pr, row, cols[0], cols[1], cols[2], cols[3], cols[4], cols[5],
                cols[6], cols[7], cur_start, cur_t0, cur_rate, offset, last_end, too_fast,
                first_too_fast, span_list, bounds, noise_start, noise_rows,
                unit0 ? Py_True : Py_False, pe);
        for (int i = 0; i < 8; i++) Py_XDECREF(cols[i]);
    }
fail_lists:
    Py_XDECREF(span_list);
    Py_XDECREF(bounds);
    (void)k0;
done:
    buf_free(&c_off);
    buf_free(&c_len);
    buf_free(&c_t);
    buf_free(&c_te);
    buf_free(&c_kind);
    buf_free(&c_unit);
    buf_free(&c_fc);
    buf_free(&c_pairs);
    PyMem_Free(spans);
    PyBuffer_Release(&view);
    PyBuffer_Release(&tview);
    PyBuffer_Release(&eview);
    PyBuffer_Release(&sview);
    PyBuffer_Release(&teview);
    PyBuffer_Release(&rview);
    return result;
}

/* ---- the store's columns, for the passes over rows ------------------------------------ */


/* One column of a FrameStore (an array.array attribute) as a buffer of the type code
 * `code`, writable if asked. 0 on success; -1 with an exception set. */
static int column(PyObject *store, const char *name, char code, int writable, Py_buffer *v) {
    PyObject *o = PyObject_GetAttrString(store, name);
    if (o == NULL) return -1;
    int r = PyObject_GetBuffer(o, v, PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0));
    Py_DECREF(o);
    if (r < 0) return -1;
    if (v->format == NULL || v->format[0] != code || v->format[1] != '\0') {
        PyErr_Format(PyExc_TypeError, "store.%s: an array of type '%c' expected", name, code);
        PyBuffer_Release(v);
        return -1;
    }
    return 0;
}

typedef struct {
    const char *name;
    char code;
    int writable;
} ColSpec;

/* Several columns at once: all or none (released again on failure). */
static int columns(PyObject *store, const ColSpec *specs, int count, Py_buffer *views) {
    for (int i = 0; i < count; i++) {
        if (column(store, specs[i].name, specs[i].code, specs[i].writable, &views[i]) < 0) {
            for (int j = 0; j < i; j++) PyBuffer_Release(&views[j]);
            return -1;
        }
    }
    return 0;
}

/* The columns the export's and the listings' row walks read (export_rows,
 * listing_rows), opened as `views` (release_all(views, ROW_COLUMNS) lets them go), and
 * the rows every one of them holds (see FrameStore.sync). */
#define ROW_COLUMNS 11
typedef struct {
    const unsigned char *kind, *channel, *status, *unit, *fc;
    const uint32_t *flags;
    const double *t_end, *t_start;
    const uint64_t *offset;
    const uint16_t *length;
    const int32_t *partner;
    Py_ssize_t n;
} RowColumns;

static int row_columns(PyObject *store, Py_buffer views[ROW_COLUMNS], RowColumns *r) {
    static const ColSpec specs[ROW_COLUMNS] = {
        {"kind", 'B', 0},   {"flags", 'I', 0},   {"t_end", 'd', 0},   {"offset", 'Q', 0},
        {"length", 'H', 0}, {"channel", 'B', 0}, {"partner", 'i', 0}, {"status", 'B', 0},
        {"unit", 'B', 0},   {"fc", 'B', 0},      {"t", 'd', 0},
    };
    if (columns(store, specs, ROW_COLUMNS, views) < 0) return -1;
    r->kind = views[0].buf;
    r->flags = views[1].buf;
    r->t_end = views[2].buf;
    r->offset = views[3].buf;
    r->length = views[4].buf;
    r->channel = views[5].buf;
    r->partner = views[6].buf;
    r->status = views[7].buf;
    r->unit = views[8].buf;
    r->fc = views[9].buf;
    r->t_start = views[10].buf;
    static const int widths[ROW_COLUMNS] = {1, 4, 8, 8, 2, 1, 4, 1, 1, 1, 8};
    Py_ssize_t n = views[0].len;
    for (int k = 1; k < ROW_COLUMNS; k++) {
        Py_ssize_t rows = views[k].len / widths[k];
        if (rows < n) n = rows;
    }
    r->n = n;
    return 0;
}

static void release_all(Py_buffer *views, int count) {
    for (int i = 0; i < count; i++) PyBuffer_Release(&views[i]);
}

/* The bytes of row i, as FrameStore.raw slices them out of its channel's stream (a
 * slice past the end is cut short). 0 on success; -1 with an exception set. */
static int row_bytes(PyObject *streams, const unsigned char *channel, const uint64_t *offset,
                     const uint16_t *length, Py_ssize_t i, const char **p, Py_ssize_t *n) {
    PyObject *key = PyLong_FromLong(channel[i]);
    if (key == NULL) return -1;
    PyObject *stream = PyDict_GetItemWithError(streams, key); /* borrowed */
    Py_DECREF(key);
    if (stream == NULL) {
        if (!PyErr_Occurred()) PyErr_Format(PyExc_KeyError, "no stream for channel %d", channel[i]);
        return -1;
    }
    if (!PyByteArray_Check(stream)) {
        PyErr_SetString(PyExc_TypeError, "a store's streams are bytearrays");
        return -1;
    }
    Py_ssize_t size = PyByteArray_GET_SIZE(stream);
    uint64_t start = offset[i], stop = start + length[i];
    if (start > (uint64_t)size) start = (uint64_t)size;
    if (stop > (uint64_t)size) stop = (uint64_t)size;
    *p = PyByteArray_AS_STRING(stream) + start;
    *n = (Py_ssize_t)(stop - start);
    return 0;
}

/* pair_rows(partner, status, fc, pairs): FrameStore.pair_rows over `pairs` (int64,
 * flat: request row, answer row, ...). */
static PyObject *py_pair_rows(PyObject *self, PyObject *args) {
    Py_buffer pv, sv, fv, qv;
    if (!PyArg_ParseTuple(args, "w*w*y*y*", &pv, &sv, &fv, &qv)) return NULL;
    PyObject *result = NULL;
    int32_t *partner = (int32_t *)pv.buf;
    unsigned char *status = (unsigned char *)sv.buf;
    const unsigned char *fc = (const unsigned char *)fv.buf;
    const int64_t *pairs = (const int64_t *)qv.buf;
    Py_ssize_t rows = sv.len, count = qv.len / 8;
    if (pv.len != 4 * rows || fv.len < rows || qv.len % 16) {
        PyErr_SetString(PyExc_ValueError, "pair_rows: columns of different lengths");
        goto done;
    }
    for (Py_ssize_t k = 0; k < count; k += 2) { /* checked first: nothing half done */
        if (pairs[k] < 0 || pairs[k] >= rows || pairs[k + 1] < 0 || pairs[k + 1] >= rows) {
            PyErr_SetString(PyExc_IndexError, "pair_rows: a row out of range");
            goto done;
        }
    }
    for (Py_ssize_t k = 0; k < count; k += 2) {
        Py_ssize_t req = (Py_ssize_t)pairs[k], resp = (Py_ssize_t)pairs[k + 1];
        partner[req] = (int32_t)resp;
        partner[resp] = (int32_t)req;
        status[req] = status[resp] = (fc[resp] & EXCEPTION_BIT) ? S_EXCEPTION : S_OK;
    }
    result = Py_None;
    Py_INCREF(result);
done:
    PyBuffer_Release(&pv);
    PyBuffer_Release(&sv);
    PyBuffer_Release(&fv);
    PyBuffer_Release(&qv);
    return result;
}

/* pair_update(store, start, open, timeout, broadcasts, last) -> (open, last)
 * Pairer.update's loop over rows start..len(store) (sniffer/framing/pairing.py), with its
 * helpers _request, _pair, _time_out and _check_retry. `open` is the open request's row
 * or -1; `broadcasts` 256 bytes, 1 for the function codes whose broadcasts are answered;
 * `last` the raw bytes of the last request that timed out (Pairer.last_timed_out). The
 * `last` returned says what Pairer.last_timed_out becomes: -2 as it was, -1 empty, a row
 * number: that row's bytes. */
static PyObject *py_pair_update(PyObject *self, PyObject *args) {
    PyObject *store;
    Py_ssize_t start, open;
    double timeout;
    Py_buffer bv, lv;
    if (!PyArg_ParseTuple(args, "Onndy*y*", &store, &start, &open, &timeout, &bv, &lv))
        return NULL;
    static const ColSpec specs[] = {
        {"kind", 'B', 0},    {"unit", 'B', 0},    {"fc", 'B', 0},      {"partner", 'i', 1},
        {"flags", 'I', 1},   {"status", 'B', 1},  {"t", 'd', 0},       {"t_end", 'd', 0},
        {"offset", 'Q', 0},  {"length", 'H', 0},  {"channel", 'B', 0},
    };
    Py_buffer c[11];
    PyObject *result = NULL, *streams = NULL;
    if (bv.len != 256) {
        PyErr_SetString(PyExc_ValueError, "pair_update: broadcasts must be 256 bytes");
        goto early;
    }
    if (columns(store, specs, 11, c) < 0) goto early;
    streams = PyObject_GetAttrString(store, "streams");
    if (streams == NULL) goto done;
    if (!PyDict_Check(streams)) {
        PyErr_SetString(PyExc_TypeError, "store.streams must be a dict");
        goto done;
    }
    const unsigned char *kind = c[0].buf, *unit = c[1].buf, *fc = c[2].buf;
    int32_t *partner = c[3].buf;
    uint32_t *flags = c[4].buf;
    unsigned char *status = c[5].buf;
    const double *t = c[6].buf, *t_end = c[7].buf;
    const uint64_t *offset = c[8].buf;
    const uint16_t *length = c[9].buf;
    const unsigned char *channel = c[10].buf;
    const unsigned char *answered = bv.buf;
    Py_ssize_t n = c[6].len / 8;
    if (c[0].len != n || c[1].len != n || c[2].len != n || c[3].len != 4 * n ||
        c[4].len != 4 * n || c[5].len != n || c[7].len != 8 * n || c[8].len != 8 * n ||
        c[9].len != 2 * n || c[10].len != n) {
        PyErr_SetString(PyExc_ValueError, "pair_update: columns of different lengths (sync)");
        goto done;
    }
    if (start < 0 || open < -1 || open >= n) {
        PyErr_SetString(PyExc_ValueError, "pair_update: start or open out of range");
        goto done;
    }
    for (Py_ssize_t i = start; i < n; i++) { /* every partner a row or -1 */
        if (partner[i] < -1 || partner[i] >= n) {
            PyErr_SetString(PyExc_ValueError, "pair_update: a partner out of range");
            goto done;
        }
    }
    /* the last timed-out request: `last_row` -2: the bytes given, -1: none, else a row */
    Py_ssize_t last_row = lv.len ? -2 : -1, last_code = -2;
    const char *last_p = lv.buf;
    Py_ssize_t last_n = lv.len;

/* _time_out(req): sets open to -1; unless answered after all, a timeout whose bytes
 * are kept for the retry check */
#define TIME_OUT(req)                                                                 \
    do {                                                                              \
        Py_ssize_t r_ = (req);                                                        \
        open = -1;                                                                    \
        if (partner[r_] == -1) {                                                      \
            status[r_] = S_TIMEOUT;                                                   \
            if (row_bytes(streams, channel, offset, length, r_, &last_p, &last_n) < 0) \
                goto done;                                                            \
            last_row = last_n ? r_ : -1;                                              \
            last_code = last_row;                                                     \
        }                                                                             \
    } while (0)

/* _check_retry(i), where the bytes kept are not empty */
#define CHECK_RETRY(i)                                                                      \
    do {                                                                                    \
        const char *p_;                                                                     \
        Py_ssize_t n_;                                                                      \
        if (row_bytes(streams, channel, offset, length, (i), &p_, &n_) < 0) goto done;      \
        if (n_ == last_n && memcmp(p_, last_p, (size_t)n_) == 0) flags[i] |= F_RETRY;       \
        last_row = -1;                                                                      \
        last_code = -1;                                                                     \
    } while (0)

    for (Py_ssize_t i = start; i < n; i++) {
        int k = kind[i];
        if (k == K_NOISE || k == K_EVENT) continue;
        Py_ssize_t op = open;
        Py_ssize_t j = partner[i];
        /* the wait is over unless this row is the open request's answer, however late
         * (the Python loop says why) */
        if (op >= 0 && t[i] - t_end[op] > timeout &&
            (j >= 0 || k == K_REQUEST || (unit[op] != unit[i] && unit[op] != 0) ||
             fc[op] != (fc[i] & 0x7F))) {
            TIME_OUT(op);
            op = -1;
        }
        if (j >= 0) { /* paired as it was framed */
            if (j < i) { /* the answer */
                if (op == j) open = -1;
                if (t[i] - t_end[j] > timeout) flags[i] |= F_LATE;
            } else { /* the request */
                if (op >= 0) TIME_OUT(op);
                if (last_row != -1) CHECK_RETRY(i);
            }
            continue;
        }
        if (k == K_REQUEST) { /* _request */
            if (open >= 0) TIME_OUT(open);
            if (unit[i] == 0 && !answered[fc[i]]) {
                status[i] = S_BROADCAST;
                open = -1;
            } else {
                status[i] = S_OPEN;
                open = i;
            }
            if (last_row != -1) CHECK_RETRY(i);
            continue;
        }
        int u = unit[i];
        if (op >= 0 && (unit[op] == u || unit[op] == 0) && fc[op] == (fc[i] & 0x7F)) {
            /* _pair(op, i) */
            unsigned char st = (flags[i] & BAD_CHECK_BITS)   ? S_BAD_ANSWER
                               : (fc[i] & EXCEPTION_BIT) ? S_EXCEPTION
                                                : S_OK;
            partner[op] = (int32_t)i;
            partner[i] = (int32_t)op;
            status[op] = status[i] = st;
            if (t[i] - t_end[op] > timeout) flags[i] |= F_LATE;
            open = -1;
        } else if (k != K_UNKNOWN) {
            status[i] = S_ORPHAN;
            if (u == 0) flags[i] |= F_ANSWERED_BROADCAST;
        }
    }
#undef TIME_OUT
#undef CHECK_RETRY
    result = Py_BuildValue("(nn)", open, last_code);
done:
    Py_XDECREF(streams);
    release_all(c, 11);
early:
    PyBuffer_Release(&bv);
    PyBuffer_Release(&lv);
    return result;
}

/* stats_scan(store, start, n, mode, unresolved)
 *   -> (noise spans, noise bytes, events, units, exception rows, open rows)
 * Stats.update's count of rows start..n (sniffer/analysis/stats.py: update, _requests, _answers)
 * but the exception codes and the open requests already remembered: `units` lists, in
 * the order each unit's first frame comes, (unit, last_seen, check errors, requests,
 * timeouts, responses, latencies left out, request times, latencies), the times and
 * latencies as float64 bytes in row order; the answers with the exception bit and the
 * requests still open come back as int64 rows for Python to finish. `mode` says which
 * latencies are kept, as pairing.measure: 0 none (no stamps), 1 those >= 0 (exact
 * stamps), 2 those not below `unresolved`. */
typedef struct {
    int seen;
    double last_seen;
    Py_ssize_t check_errors, requests, timeouts, responses, left_out;
    Buf times, latencies;
} UnitTally;

static PyObject *py_stats_scan(PyObject *self, PyObject *args) {
    PyObject *store;
    Py_ssize_t start, n;
    int mode;
    double unresolved;
    if (!PyArg_ParseTuple(args, "Onnid", &store, &start, &n, &mode, &unresolved)) return NULL;
    static const ColSpec specs[] = {
        {"kind", 'B', 0}, {"unit", 'B', 0},    {"fc", 'B', 0}, {"partner", 'i', 0},
        {"flags", 'I', 0}, {"status", 'B', 0}, {"t", 'd', 0},  {"t_end", 'd', 0},
        {"length", 'H', 0},
    };
    Py_buffer c[9];
    if (columns(store, specs, 9, c) < 0) return NULL;
    PyObject *result = NULL, *list = NULL;
    UnitTally *tally = PyMem_Calloc(256, sizeof(UnitTally));
    Buf exceptions = {0}, open_rows = {0};
    unsigned char order[256];
    int n_units = 0;
    if (tally == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    const unsigned char *kind = c[0].buf, *unit = c[1].buf, *fc = c[2].buf, *status = c[5].buf;
    const int32_t *partner = c[3].buf;
    const uint32_t *flags = c[4].buf;
    const double *t = c[6].buf, *t_end = c[7].buf;
    const uint16_t *length = c[8].buf;
    Py_ssize_t rows = c[6].len / 8;
    if (c[0].len != rows || c[1].len != rows || c[2].len != rows || c[3].len != 4 * rows ||
        c[4].len != 4 * rows || c[5].len != rows || c[7].len != 8 * rows ||
        c[8].len != 2 * rows) {
        PyErr_SetString(PyExc_ValueError, "stats_scan: columns of different lengths (sync)");
        goto done;
    }
    if (start < 0 || n > rows || start > n) {
        PyErr_SetString(PyExc_ValueError, "stats_scan: rows out of range");
        goto done;
    }
    Py_ssize_t spans = 0, noise_bytes = 0, events = 0;
    for (Py_ssize_t i = start; i < n; i++) {
        int k = kind[i];
        if (k == K_NOISE) {
            spans += 1;
            noise_bytes += length[i];
            continue;
        }
        if (k == K_EVENT) {
            events += 1;
            continue;
        }
        int u = unit[i];
        UnitTally *ut = &tally[u];
        if (!ut->seen) {
            ut->seen = 1;
            order[n_units++] = (unsigned char)u;
        }
        ut->last_seen = t_end[i];
        if (flags[i] & BAD_CHECK_BITS) {
            ut->check_errors += 1;
            continue;
        }
        if (k == K_REQUEST) {
            ut->requests += 1;
            if (buf_put(&ut->times, &t[i], 8) < 0) goto done;
            if (status[i] == S_TIMEOUT) {
                ut->timeouts += 1;
            } else if (status[i] == S_OPEN) {
                int64_t row = i;
                if (buf_put(&open_rows, &row, 8) < 0) goto done;
            }
        } else if (k == K_RESPONSE || k == K_EXCEPTION) {
            ut->responses += 1;
            if (fc[i] & EXCEPTION_BIT) {
                int64_t row = i;
                if (buf_put(&exceptions, &row, 8) < 0) goto done;
            }
            Py_ssize_t p = partner[i];
            if (p == -1) continue;
            if (p < 0) p += rows; /* as Python indexes */
            if (p < 0 || p >= rows) {
                PyErr_SetString(PyExc_IndexError, "stats_scan: a partner out of range");
                goto done;
            }
            double raw = t[i] - t_end[p];
            int kept = mode == 0 ? 0 : mode == 1 ? raw >= 0.0 : !(raw < unresolved);
            if (kept) {
                if (buf_put(&ut->latencies, &raw, 8) < 0) goto done;
            } else {
                ut->left_out += 1;
            }
        }
    }
    list = PyList_New(n_units);
    if (list == NULL) goto done;
    for (int j = 0; j < n_units; j++) {
        UnitTally *ut = &tally[order[j]];
        PyObject *times = buf_bytes(&ut->times), *lat = buf_bytes(&ut->latencies), *item = NULL;
        if (times && lat)
            item = Py_BuildValue("(idnnnnnOO)", (int)order[j], ut->last_seen, ut->check_errors,
                                 ut->requests, ut->timeouts, ut->responses, ut->left_out, times,
                                 lat);
        Py_XDECREF(times);
        Py_XDECREF(lat);
        if (item == NULL) goto done;
        PyList_SET_ITEM(list, j, item);
    }
    {
        PyObject *e = buf_bytes(&exceptions), *o = buf_bytes(&open_rows);
        if (e && o) result = Py_BuildValue("(nnnOOO)", spans, noise_bytes, events, list, e, o);
        Py_XDECREF(e);
        Py_XDECREF(o);
    }
done:
    Py_XDECREF(list);
    if (tally != NULL) {
        for (int u = 0; u < 256; u++) {
            buf_free(&tally[u].times);
            buf_free(&tally[u].latencies);
        }
        PyMem_Free(tally);
    }
    buf_free(&exceptions);
    buf_free(&open_rows);
    release_all(c, 9);
    return result;
}

/* mask_rows(mask, start) -> rows: `start + k` for each k where mask[k] is not 0, as
 * int64, in order: `array("q", compress(range(start, start + len(mask)), mask))`, which
 * made a Python int of each row it took (SunSpecTracker.follow_mask; 42 ms of 1M rows'
 * export, 2026-12-07). */
static PyObject *py_mask_rows(PyObject *self, PyObject *args) {
    Py_buffer mv;
    long long start;
    if (!PyArg_ParseTuple(args, "y*L", &mv, &start)) return NULL;
    const unsigned char *m = mv.buf;
    Py_ssize_t n = mv.len, count = 0;
    for (Py_ssize_t k = 0; k < n; k++) count += m[k] != 0;
    PyObject *result = PyBytes_FromStringAndSize(NULL, count * 8);
    if (result != NULL) {
        int64_t *out = (int64_t *)PyBytes_AS_STRING(result);
        for (Py_ssize_t k = 0, w = 0; k < n; k++)
            if (m[k]) out[w++] = (int64_t)start + (int64_t)k;
    }
    PyBuffer_Release(&mv);
    return result;
}

/* sunspec_rows(store, rows, at, known, skip, bases, reads, frames) -> positions
 * The cheap half of SunSpecTracker.follow_rows (sniffer/meaning/sunspec.py), by the rule
 * Python hands over: of rows[at:] (int64), the positions (int64) of those it may take:
 * answers to a read of `reads` (256 bytes, 1 for a function code SunSpec reads) with a
 * good check, paired, of a unit not in `skip`, whose request either is an ASCII frame
 * (Python decodes it) or holds a read's PDU where its envelope puts it and is of a unit
 * in `known` or reads a range that holds one of `bases` and the register after it.
 * `frames` (int64): the bytes before an RTU request's function code and after its PDU,
 * the same for a Modbus TCP request (MBAP header), then the length of a read's PDU
 * (function code, first register, count). `known` and `skip` are 256 bytes, 1 for a
 * unit; `bases` int64, sorted. Rows this cannot read (a partner or stream out of range)
 * are kept, for Python to decide as it always did. */
static PyObject *py_sunspec_rows(PyObject *self, PyObject *args) {
    PyObject *store;
    Py_buffer rv, kv, sv, bv, fv, ev;
    Py_ssize_t at;
    if (!PyArg_ParseTuple(args, "Oy*ny*y*y*y*y*", &store, &rv, &at, &kv, &sv, &bv, &fv, &ev))
        return NULL;
    static const ColSpec specs[] = {
        {"fc", 'B', 0},     {"flags", 'I', 0},  {"partner", 'i', 0}, {"unit", 'B', 0},
        {"offset", 'Q', 0}, {"length", 'H', 0}, {"channel", 'B', 0},
    };
    Py_buffer c[7];
    PyObject *result = NULL, *streams = NULL;
    Buf out = {0};
    if (kv.len != 256 || sv.len != 256 || fv.len != 256 || rv.len % 8 || bv.len % 8 ||
        ev.len != 5 * 8) {
        PyErr_SetString(PyExc_ValueError, "sunspec_rows: bad masks or arrays");
        goto early;
    }
    const int64_t *frame = ev.buf;
    /* bytes before the function code and after the PDU: RTU, then Modbus TCP; the PDU */
    const int64_t rtu_head = frame[0], rtu_tail = frame[1], tcp_head = frame[2],
                  tcp_tail = frame[3], pdu = frame[4];
    if (rtu_head < 0 || rtu_tail < 0 || tcp_head < 0 || tcp_tail < 0 || pdu < 5) {
        PyErr_SetString(PyExc_ValueError, "sunspec_rows: bad frame layout");
        goto early;
    }
    if (columns(store, specs, 7, c) < 0) goto early;
    streams = PyObject_GetAttrString(store, "streams");
    if (streams == NULL) goto done;
    if (!PyDict_Check(streams)) {
        PyErr_SetString(PyExc_TypeError, "store.streams must be a dict");
        goto done;
    }
    const unsigned char *fc = c[0].buf, *unit = c[3].buf, *channel = c[6].buf;
    const uint32_t *flags = c[1].buf;
    const int32_t *partner = c[2].buf;
    const uint64_t *offset = c[4].buf;
    const uint16_t *length = c[5].buf;
    const unsigned char *known = kv.buf, *skip = sv.buf, *reads = fv.buf;
    const int64_t *rows = rv.buf, *bases = bv.buf;
    Py_ssize_t count = rv.len / 8, n_bases = bv.len / 8, n = c[0].len;
    if (c[1].len != 4 * n || c[2].len != 4 * n || c[3].len != n || c[4].len != 8 * n ||
        c[5].len != 2 * n || c[6].len != n) {
        PyErr_SetString(PyExc_ValueError, "sunspec_rows: columns of different lengths (sync)");
        goto done;
    }
    for (Py_ssize_t k = at < 0 ? 0 : at; k < count; k++) {
        int64_t i = rows[k];
        int keep = 1;
        if (i >= 0 && i < n) {
            int64_t req = partner[i];
            if (!reads[fc[i]] || flags[i] & F_CHECK_BAD || req == -1 || skip[unit[i]]) {
                keep = 0;
            } else if (req >= 0 && req < n && !(flags[req] & F_ASCII)) {
                int tcp = (flags[req] & F_MBAP) != 0;
                int64_t head = tcp ? tcp_head : rtu_head, tail = tcp ? tcp_tail : rtu_tail;
                if (length[req] < head + pdu + tail) {
                    keep = 0;
                } else if (!known[unit[i]]) {
                    const char *p;
                    Py_ssize_t got;
                    if (row_bytes(streams, channel, offset, length, (Py_ssize_t)req, &p, &got) < 0)
                        goto done;
                    if (got >= head + pdu) {
                        const unsigned char *q = (const unsigned char *)p + head;
                        int64_t first = q[1] << 8 | q[2], regs = q[3] << 8 | q[4];
                        keep = 0; /* the smallest base at or after `first` must fit */
                        for (Py_ssize_t b = 0; b < n_bases; b++) {
                            if (bases[b] >= first) {
                                keep = bases[b] + 2 <= first + regs;
                                break;
                            }
                        }
                    }
                }
            }
        }
        if (keep) {
            int64_t position = k;
            if (buf_put(&out, &position, 8) < 0) goto done;
        }
    }
    result = buf_bytes(&out);
done:
    Py_XDECREF(streams);
    release_all(c, 7);
early:
    buf_free(&out);
    PyBuffer_Release(&rv);
    PyBuffer_Release(&kv);
    PyBuffer_Release(&sv);
    PyBuffer_Release(&bv);
    PyBuffer_Release(&fv);
    PyBuffer_Release(&ev);
    return result;
}

/* join_reads(batches) -> (data, ends, t_starts, t_ends)
 * Consecutive batches of reads (sniffer/sources/reads.py: Reads) as one: their bytes
 * joined, each read's end offset moved by the bytes of the batches before it (int64),
 * the times (float64) one after the other (sniffer/framing/pipeline.py: _joined). */
static PyObject *py_join_reads(PyObject *self, PyObject *arg) {
    if (!PyList_Check(arg)) {
        PyErr_SetString(PyExc_TypeError, "join_reads: a list of batches");
        return NULL;
    }
    Buf data = {0}, ends = {0}, starts = {0}, tends = {0};
    PyObject *result = NULL;
    int64_t before = 0;
    {
        /* the joined sizes first, so that each buffer is allocated once (a batch held is
         * up to HOLD_BYTES of reads: doubling from 256 bytes copies it about once more) */
        Py_ssize_t n_data = 0, n_reads = 0;
        for (Py_ssize_t b = 0; b < PyList_GET_SIZE(arg); b++) {
            PyObject *batch = PyList_GET_ITEM(arg, b);
            PyObject *d = PyObject_GetAttrString(batch, "data");
            PyObject *e = d != NULL ? PyObject_GetAttrString(batch, "ends") : NULL;
            Py_ssize_t nd = d != NULL ? PyObject_Length(d) : -1;
            Py_ssize_t ne = e != NULL ? PyObject_Length(e) : -1;
            Py_XDECREF(d);
            Py_XDECREF(e);
            if (nd < 0 || ne < 0) {
                PyErr_Clear(); /* the loop below says what is wrong */
                n_data = n_reads = 0;
                break;
            }
            n_data += nd;
            n_reads += ne;
        }
        if (buf_reserve(&data, n_data) < 0 || buf_reserve(&ends, 8 * n_reads) < 0 ||
            buf_reserve(&starts, 8 * n_reads) < 0 || buf_reserve(&tends, 8 * n_reads) < 0)
            goto done;
    }
    for (Py_ssize_t b = 0; b < PyList_GET_SIZE(arg); b++) {
        PyObject *batch = PyList_GET_ITEM(arg, b);
        static const char *names[4] = {"data", "ends", "t_starts", "t_ends"};
        static const char codes[4] = {0, 'q', 'd', 'd'};
        Py_buffer v[4];
        int got = 0;
        for (; got < 4; got++) {
            PyObject *o = PyObject_GetAttrString(batch, names[got]);
            if (o == NULL) break;
            int r = PyObject_GetBuffer(o, &v[got], codes[got] ? PyBUF_FORMAT : PyBUF_SIMPLE);
            Py_DECREF(o);
            if (r < 0) break;
            if (codes[got] && (v[got].format == NULL || v[got].format[0] != codes[got] ||
                               v[got].format[1] != '\0')) {
                PyErr_Format(PyExc_TypeError, "join_reads: %s of type '%c' expected", names[got],
                             codes[got]);
                PyBuffer_Release(&v[got]);
                break;
            }
        }
        int ok = got == 4 && v[1].len == v[2].len && v[1].len == v[3].len;
        if (got == 4 && !ok) PyErr_SetString(PyExc_ValueError, "join_reads: arrays of different lengths");
        if (ok) {
            const int64_t *e = v[1].buf;
            Py_ssize_t count = v[1].len / 8;
            ok = buf_put(&data, v[0].buf, v[0].len) == 0 && buf_put(&starts, v[2].buf, v[2].len) == 0 &&
                 buf_put(&tends, v[3].buf, v[3].len) == 0;
            for (Py_ssize_t k = 0; ok && k < count; k++) {
                int64_t moved = e[k] + before;
                ok = buf_put(&ends, &moved, 8) == 0;
            }
            before += v[0].len;
        }
        for (int i = 0; i < got; i++) PyBuffer_Release(&v[i]);
        if (!ok) goto done;
    }
    {
        PyObject *d = buf_bytes(&data), *e = buf_bytes(&ends), *s = buf_bytes(&starts),
                 *te = buf_bytes(&tends);
        if (d && e && s && te) result = PyTuple_Pack(4, d, e, s, te);
        Py_XDECREF(d);
        Py_XDECREF(e);
        Py_XDECREF(s);
        Py_XDECREF(te);
    }
done:
    buf_free(&data);
    buf_free(&ends);
    buf_free(&starts);
    buf_free(&tends);
    return result;
}

/* ranked(values, ranks, gaps) -> the values at those ranks of the sorted values, or None
 * sniffer/analysis/stats.py's nearest-rank quantiles (sorted(values)[rank]) without sorting: each
 * rank found by selection. `values` is float64 (an array 'd'); with `gaps`, the values
 * are the differences of consecutive ones, b - a (median_gap). None when a NaN or a
 * negative zero is among them: sorted() puts a NaN where the order of the values leaves
 * it, and -0.0 where it came among equal zeros, so only a sort says; Python sorts then.
 * Without either the values are in a total order and the value at each rank is the one
 * sorted() puts there. `ranks` ascending, each < the number of values. */
static void swap_d(double *a, double *b) {
    double t = *a;
    *a = *b;
    *b = t;
}

/* leaves the k-th smallest of v[lo..hi] at v[k], smaller ones before, larger after */
static void select_kth(double *v, Py_ssize_t lo, Py_ssize_t hi, Py_ssize_t k) {
    while (hi > lo) {
        Py_ssize_t mid = lo + (hi - lo) / 2; /* median of three as the pivot */
        if (v[mid] < v[lo]) swap_d(&v[mid], &v[lo]);
        if (v[hi] < v[lo]) swap_d(&v[hi], &v[lo]);
        if (v[hi] < v[mid]) swap_d(&v[hi], &v[mid]);
        double pivot = v[mid];
        Py_ssize_t i = lo, j = hi;
        while (i <= j) {
            while (v[i] < pivot) i++;
            while (pivot < v[j]) j--;
            if (i <= j) {
                swap_d(&v[i], &v[j]);
                i++;
                j--;
            }
        }
        if (k <= j) hi = j;
        else if (k >= i) lo = i;
        else return; /* between: equal to the pivot */
    }
}

static PyObject *py_ranked(PyObject *self, PyObject *args) {
    Py_buffer vv;
    PyObject *ranks;
    int gaps;
    if (!PyArg_ParseTuple(args, "y*O!p", &vv, &PyTuple_Type, &ranks, &gaps)) return NULL;
    PyObject *result = NULL;
    double *v = NULL;
    Py_ssize_t n = vv.len / 8;
    const double *src = vv.buf;
    if (vv.len % 8) {
        PyErr_SetString(PyExc_TypeError, "ranked: float64 values");
        goto done;
    }
    if (gaps) n = n > 0 ? n - 1 : 0;
    v = PyMem_Malloc(sizeof(double) * (size_t)(n ? n : 1));
    if (v == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        double x = gaps ? src[i + 1] - src[i] : src[i];
        if (isnan(x) || (x == 0.0 && signbit(x))) {
            result = Py_None; /* only a sort says */
            Py_INCREF(result);
            goto done;
        }
        v[i] = x;
    }
    Py_ssize_t count = PyTuple_GET_SIZE(ranks), lo = 0;
    result = PyTuple_New(count);
    if (result == NULL) goto done;
    for (Py_ssize_t j = 0; j < count; j++) {
        Py_ssize_t k = PyLong_AsSsize_t(PyTuple_GET_ITEM(ranks, j));
        if (k == -1 && PyErr_Occurred()) goto fail;
        if (k < lo || k >= n) {
            PyErr_SetString(PyExc_ValueError, "ranked: ranks ascending and within the values");
            goto fail;
        }
        select_kth(v, lo, n - 1, k);
        PyObject *x = PyFloat_FromDouble(v[k]);
        if (x == NULL) goto fail;
        PyTuple_SET_ITEM(result, j, x);
        lo = k; /* the next rank lies at or after this one */
    }
    goto done;
fail:
    Py_CLEAR(result);
done:
    PyMem_Free(v);
    PyBuffer_Release(&vv);
    return result;
}

/* defined below, with the poll cycle's and the tallies' loops */
static PyObject *py_poll_table(PyObject *self, PyObject *rules);
static PyObject *py_poll_block(PyObject *self, PyObject *args);
static PyObject *py_tally_latencies(PyObject *self, PyObject *args);
static PyObject *py_tally_gaps(PyObject *self, PyObject *args);

/* ---- the Wireshark export's packets ---------------------------------------------------- */

/* export_table() -> a table of the content keys one PcapExporter met (sniffer/outputs/export.py:
 * PcapExporter.write), each with the packet template Python made for its content: the
 * tuple (first, head, middle, tail, spliced) of PcapExporter._template. A key is a row's
 * content key as Describer.contents makes it (sniffer/meaning/describe.py): "E" or, for an answer
 * with a request, "A" with the bytes, kind, flags, status (and the request's bytes and
 * mode); or "F" with what an answer shares with the answers that differ from it only in
 * their values (`_valueless`). The keys live in an arena; at EX_MAX_KEYS the table starts
 * empty again (it holds templates Python keeps anyway, in their contents' memo). The slots
 * start at EX_FIRST_SLOTS and double as keys come, kept at most half full: a capture
 * holds some hundreds of keys (250 to 640 in 200k frames of four benchmark mixes), and
 * the 16,384 slots they were spread over (512 KiB) made nearly every lookup a cache miss
 * (7 % of an export's time, the largest single function). */
#define EX_MAX_KEYS 8192
#define EX_SLOTS (2 * EX_MAX_KEYS)
#define EX_FIRST_SLOTS 1024
#define EX_RUN_BYTES (1 << 16)
#define EX_MAX_TIME 1e10 /* later packet times are left to Python (its ticks pass 64 bits) */

typedef struct {
    uint64_t hash;
    Py_ssize_t at, size;
    PyObject *template; /* NULL: an empty slot */
} ExSlot;

typedef struct {
    ExSlot *slots;
    Py_ssize_t cap; /* slots: a power of 2, EX_FIRST_SLOTS to EX_SLOTS */
    Py_ssize_t used;
    Buf arena;
    Buf out, exact, free_key, packet_key; /* the blocks and keys of a run, kept for the next */
    int running;                          /* a run is under way (miss must not start one) */
} ExTable;

static void ex_clear(ExTable *et) {
    for (Py_ssize_t k = 0; k < et->cap; k++) Py_CLEAR(et->slots[k].template);
    et->used = 0;
    et->arena.n = 0;
}

/* The first slots of a new table: 0, or -1 with an exception set. */
static int ex_init(ExTable *et) {
    et->slots = PyMem_Calloc(EX_FIRST_SLOTS, sizeof(ExSlot));
    if (et->slots == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    et->cap = EX_FIRST_SLOTS;
    return 0;
}

/* Twice the slots, every key moved to its place among them: 0, or -1 with an exception
 * set (the table as it was). */
static int ex_grow(ExTable *et) {
    Py_ssize_t cap = 2 * et->cap;
    ExSlot *slots = PyMem_Calloc((size_t)cap, sizeof(ExSlot));
    if (slots == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    for (Py_ssize_t k = 0; k < et->cap; k++) {
        if (et->slots[k].template == NULL) continue;
        Py_ssize_t j = (Py_ssize_t)(et->slots[k].hash & (uint64_t)(cap - 1));
        while (slots[j].template != NULL) j = (j + 1) & (cap - 1);
        slots[j] = et->slots[k];
    }
    PyMem_Free(et->slots);
    et->slots = slots;
    et->cap = cap;
    return 0;
}

static void ex_table_free(PyObject *capsule) {
    ExTable *et = PyCapsule_GetPointer(capsule, "modscope.export_table");
    if (et == NULL) return;
    if (et->slots != NULL) ex_clear(et);
    PyMem_Free(et->slots);
    buf_free(&et->arena);
    buf_free(&et->out);
    buf_free(&et->exact);
    buf_free(&et->free_key);
    buf_free(&et->packet_key);
    PyMem_Free(et);
}

static PyObject *py_export_table(PyObject *self, PyObject *unused) {
    ExTable *et = PyMem_Calloc(1, sizeof(ExTable));
    if (et == NULL) return PyErr_NoMemory();
    if (ex_init(et) < 0) {
        PyMem_Free(et);
        return NULL;
    }
    PyObject *capsule = PyCapsule_New(et, "modscope.export_table", ex_table_free);
    if (capsule == NULL) {
        PyMem_Free(et->slots);
        PyMem_Free(et);
    }
    return capsule;
}

/* A key's hash, eight bytes a step: the keys hold a frame's bytes and its request's
 * (up to some 500 bytes), hashed for nearly every row, and a byte a step (FNV-1a, one
 * dependent multiply a byte) was most of the lookup's cost. Each word is mixed in with
 * a multiply; the remaining bytes as one word; then splitmix64's finaliser, so that the
 * low bits the table indexes by depend on every byte. */
static uint64_t ex_hash(const unsigned char *p, Py_ssize_t n) {
    uint64_t h = 0x9e3779b97f4a7c15ull ^ (uint64_t)n, w;
    Py_ssize_t k = 0;
    for (; k + 8 <= n; k += 8) {
        memcpy(&w, p + k, 8);
        h = (h ^ w) * 0xff51afd7ed558ccdull;
        h ^= h >> 32;
    }
    w = 0;
    memcpy(&w, p + k, (size_t)(n - k));
    h = (h ^ w) * 0xff51afd7ed558ccdull;
    h ^= h >> 30;
    h *= 0xbf58476d1ce4e5b9ull;
    h ^= h >> 27;
    h *= 0x94d049bb133111ebull;
    return h ^ (h >> 31);
}

/* The slot of key (p, n): the one holding it, or the empty one it would go in. */
static ExSlot *ex_slot(ExTable *et, uint64_t h, const char *p, Py_ssize_t n) {
    Py_ssize_t mask = et->cap - 1, k = (Py_ssize_t)(h & (uint64_t)mask);
    for (;;) {
        ExSlot *s = &et->slots[k];
        if (s->template == NULL) return s;
        if (s->hash == h && s->size == n && memcmp(et->arena.p + s->at, p, (size_t)n) == 0)
            return s;
        k = (k + 1) & mask;
    }
}

/* A template as PcapExporter._template makes it, checked once when it is kept. */
static int ex_template_ok(PyObject *t) {
    if (!PyTuple_CheckExact(t) || PyTuple_GET_SIZE(t) != 5) return 0;
    for (int k = 0; k < 3; k++)
        if (!PyBytes_CheckExact(PyTuple_GET_ITEM(t, k))) return 0;
    PyObject *tail = PyTuple_GET_ITEM(t, 3), *spliced = PyTuple_GET_ITEM(t, 4);
    if (tail != Py_None && !PyBytes_CheckExact(tail)) return 0;
    if (spliced == Py_None) return 1;
    if (!PyTuple_CheckExact(spliced) || PyTuple_GET_SIZE(spliced) != 4) return 0;
    for (int k = 0; k < 4; k++)
        if (!PyBytes_CheckExact(PyTuple_GET_ITEM(spliced, k))) return 0;
    return 1;
}

static int ex_keep(ExTable *et, const Buf *key, PyObject *template) {
    uint64_t h = ex_hash((const unsigned char *)key->p, key->n);
    ExSlot *s = ex_slot(et, h, key->p, key->n);
    if (s->template == NULL) {
        if (et->used >= EX_MAX_KEYS) {
            ex_clear(et);
            s = ex_slot(et, h, key->p, key->n);
        } else if (2 * (et->used + 1) > et->cap) {
            if (ex_grow(et) < 0) return -1;
            s = ex_slot(et, h, key->p, key->n);
        }
        s->hash = h;
        s->at = et->arena.n;
        s->size = key->n;
        if (buf_put(&et->arena, key->p, key->n) < 0) return -1;
        et->used += 1;
    }
    Py_INCREF(template);
    Py_XSETREF(s->template, template);
    return 0;
}

static int ex_put_bytes(Buf *b, PyObject *o) {
    return buf_put(b, PyBytes_AS_STRING(o), PyBytes_GET_SIZE(o));
}

/* `raw.hex(" ")`, as bytes.hex writes it (lower case). */
static int ex_put_hex(Buf *b, const unsigned char *p, Py_ssize_t n) {
    static const char digits[] = "0123456789abcdef";
    if (n == 0) return 0;
    char text[3 * 64];
    for (Py_ssize_t k = 0; k < n; k += 64) {
        Py_ssize_t m = n - k < 64 ? n - k : 64, w = 0;
        for (Py_ssize_t j = 0; j < m; j++) {
            if (k + j) text[w++] = ' ';
            text[w++] = digits[p[k + j] >> 4];
            text[w++] = digits[p[k + j] & 15];
        }
        if (buf_put(b, text, w) < 0) return -1;
    }
    return 0;
}

static int ex_put_u8(Buf *b, unsigned v) {
    unsigned char c = (unsigned char)v;
    return buf_put(b, &c, 1);
}

static int ex_put_u16(Buf *b, Py_ssize_t v) {
    uint16_t x = (uint16_t)v;
    return buf_put(b, &x, 2);
}

static int ex_put_u32(Buf *b, uint32_t v) {
    return buf_put(b, &v, 4);
}

/* Whether `unit` is a key of the dict `units`: 1, 0, or -1 with an exception set. */
static int ex_in(PyObject *units, unsigned unit) {
    if (!PyDict_GET_SIZE(units)) return 0;
    PyObject *u = PyLong_FromLong((long)unit);
    if (u == NULL) return -1;
    int in = PyDict_Contains(units, u);
    Py_DECREF(u);
    return in;
}

/* ... of any of the dicts of the tuple `apart`. */
static int ex_in_any(PyObject *apart, unsigned unit) {
    for (Py_ssize_t a = 0; a < PyTuple_GET_SIZE(apart); a++) {
        int in = ex_in(PyTuple_GET_ITEM(apart, a), unit);
        if (in) return in;
    }
    return 0;
}

/* A block's time: `time_ticks(t, TICKS)` as PcapExporter._rows inlines it, high word
 * first. */
static void ex_time(double t, uint32_t words[2]) {
    double whole = floor(t);
    uint64_t ticks = (uint64_t)whole * 1000000000ull + (uint64_t)nearbyint((t - whole) * 1e9);
    words[0] = (uint32_t)(ticks >> 32);
    words[1] = (uint32_t)(ticks & 0xFFFFFFFFu);
}

/* Whether a padding bit of `last`, the last data byte of bits sent for `quantity`
 * values, is set: the bits after the quantity (none when it is a multiple of 8). What
 * the dissector says of them (dissectors/pdu/access.py: checked_values) is one problem
 * whose text names the quantity only, "padding bits after N values are not zero", so
 * the packets of two such frames differ only in their bytes when this is the same. */
static unsigned ex_padded(unsigned last, Py_ssize_t quantity) {
    unsigned used = (unsigned)(quantity % 8);
    return used && (last & (0xFFu << used) & 0xFFu) ? 1 : 0;
}

/* The "W" key of an RTU row of a unit with no dictionary (not a SunSpec unit), none of
 * whose flags (nor its request's) is one of describe.py's VALUED_FLAGS: what decides its
 * Modbus/TCP packet (PcapExporter._tcp_packet) but for the bytes the splice puts in (its
 * unit and PDU, its hex and CRC in the comment), for the rows whose other bytes decide
 * nothing else in it. Such a packet holds the row's bytes and the problems
 * `Describer._content` finds, and with no dictionary those are the dissector's
 * (dissectors/pdu; public codes, which a dictionary cannot redefine), which for these
 * rows read no other bytes than the key's (an address is only ever said in the summary,
 * which the packet does not hold; a unit only as "the broadcast address 0"):
 *  - FC 1-6 requests (8 bytes): the quantity (its limits) or, for FC 5, the value (FF00
 *    or 0000); FC 6's value is not checked;
 *  - FC 15, 16 requests whose byte count is the bytes that follow (and, for FC 15, what
 *    the quantity needs): quantity (its limits), byte count (checked against the
 *    quantity) and, for FC 15, whether a padding bit after the quantity is set (in the
 *    last byte: `ex_padded`);
 *  - FC 5, 6 echoes, byte for byte their request's: as their request;
 *  - FC 15, 16 answers (8 bytes) whose unit, code, address and quantity are their
 *    request's (the echo compares these): the quantity, the request's byte count and
 *    length (what parsing it reads; its values are not read);
 *  - FC 1-4 answers whose byte count is the bytes that follow and what the quantity
 *    asked needs (request: 8 bytes, same code): the byte count and, for bits, the
 *    quantity and whether a padding bit is set (`ex_padded`);
 *  - exceptions (5 bytes): the exception code, the request's code (another code than
 *    the answer's is a problem) and length.
 * Kind, flags, status, length, code and whether the unit is 0 are in every key.
 * 1: made; 0: none; -1: no memory. */
static int ex_packet_key(Buf *w, unsigned k, uint32_t fl, unsigned st, const unsigned char *r,
                         Py_ssize_t rn, const unsigned char *q, Py_ssize_t qn) {
    w->n = 0;
    if (rn < 5) return 0;
    unsigned code = r[1];
    const unsigned char *last = r + rn - 3; /* the last byte before the CRC */
    Py_ssize_t quantity = qn >= 6 ? (q[4] << 8 | q[5]) : 0;
    int made = 0; /* 1: a key of this row's kind is being made */
    if (buf_put(w, "W", 1) < 0 || ex_put_u8(w, k) < 0 || ex_put_u32(w, fl) < 0 ||
        ex_put_u8(w, st) < 0 || ex_put_u16(w, rn) < 0 || ex_put_u8(w, r[0] == 0) < 0 ||
        ex_put_u8(w, code) < 0)
        return -1;
    if (k == K_REQUEST) {
        int single = FC_WRITE_SINGLE(code);
        if ((FC_READ(code) || single) && rn == TABLE_REQUEST_LENGTH) {
            made = 1;
            if ((!single || FC_WRITE_COIL(code)) && buf_put(w, r + 4, 2) < 0) return -1;
        } else if (FC_WRITE_MULTIPLE(code) && rn >= MULTIPLE_BASE &&
                   rn == MULTIPLE_BASE + r[MULTIPLE_COUNT_AT]) {
            int coils = FC_WRITE_COILS(code);
            Py_ssize_t asked = r[4] << 8 | r[5];
            made = !coils || r[MULTIPLE_COUNT_AT] == (asked + 7) / 8;
            if (made && (buf_put(w, r + 4, 3) < 0 ||
                         (coils && ex_put_u8(w, ex_padded(*last, asked)) < 0)))
                return -1;
        }
    } else if (code & EXCEPTION_BIT) {
        made = rn == EXCEPTION_LENGTH && qn >= 2;
        if (made && (buf_put(w, r + 2, 1) < 0 || buf_put(w, q + 1, 1) < 0 ||
                     ex_put_u16(w, qn) < 0))
            return -1;
    } else if (FC_WRITE_SINGLE(code)) {
        made = rn == TABLE_REQUEST_LENGTH && qn == TABLE_REQUEST_LENGTH &&
               memcmp(r, q, TABLE_REQUEST_LENGTH) == 0;
        if (made && FC_WRITE_COIL(code) && buf_put(w, r + 4, 2) < 0) return -1;
    } else if (FC_WRITE_MULTIPLE(code)) {
        made = rn == TABLE_REQUEST_LENGTH && qn > MULTIPLE_COUNT_AT && memcmp(r, q, 6) == 0;
        if (made && (buf_put(w, r + 4, 2) < 0 || buf_put(w, q + MULTIPLE_COUNT_AT, 1) < 0 ||
                     ex_put_u16(w, qn) < 0))
            return -1;
    } else if (FC_READ(code)) {
        int bits = FC_READ_BITS(code);
        Py_ssize_t need = bits ? (quantity + 7) / 8 : 2 * quantity;
        made = qn == TABLE_REQUEST_LENGTH && q[1] == code && rn == READ_ANSWER_BASE + r[2] &&
               r[2] == need;
        if (made && (buf_put(w, r + 2, 1) < 0 ||
                     (bits && (ex_put_u8(w, ex_padded(*last, quantity)) < 0 ||
                               buf_put(w, q + 4, 2) < 0))))
            return -1;
    }
    return made;
}

/* A row's exact content key, as Describer.contents makes it, in bytes: "E" or, for an
 * answer with a request, "A"; the row's kind, flags, status and bytes, and an answer's
 * request's mode flags and bytes. 0, or -1 with no memory. */
static int ex_exact_key(Buf *w, int answer, unsigned k, uint32_t fl, unsigned st,
                        const char *raw, Py_ssize_t raw_n, uint32_t asked_mode,
                        const char *asked, Py_ssize_t asked_n) {
    w->n = 0;
    if (buf_put(w, answer ? "A" : "E", 1) < 0 || ex_put_u8(w, k) < 0 || ex_put_u32(w, fl) < 0 ||
        ex_put_u8(w, st) < 0 || ex_put_u16(w, raw_n) < 0 || buf_put(w, raw, raw_n) < 0)
        return -1;
    if (answer && (ex_put_u32(w, asked_mode) < 0 || ex_put_u16(w, asked_n) < 0 ||
                   buf_put(w, asked, asked_n) < 0))
        return -1;
    return 0;
}

/* export_rows(table, store, rows, notes, apart, bound, alike, slow, mode, valued, miss,
 *             limit, char, mbap[, base]) -> (blocks, rows, found, more)
 * PcapExporter.write's loop (sniffer/outputs/export.py) over up to `limit` rows taken from the
 * iterator `rows`: the enhanced packet blocks of the rows whose content key `table`
 * holds, made from its template as Python makes them (the time's ticks as time_ticks
 * rounds them, the MBAP transaction id, and, for a Modbus/TCP packet (`alike`) of other
 * bytes than the template's first row, those bytes spliced in as _splice does). Every
 * other row is handed to `miss(row)`, which returns (its block, the template of its
 * content or None): the template is kept under the row's keys unless the row is one
 * Describer.contents shares no content for (an event, a row with a note, a unit of
 * `apart` (the SunSpec units, then the units with parameter windows), an exception its
 * request may explain (a unit of `bound`, or a request of a SunSpec unit)) or
 * one whose packet says more than its content (the `slow` flag). `bound`: the units
 * with a dictionary (no "F" key); `mode`, `valued`: the flags of _MODE, VALUED_FLAGS.
 * A packet's time is export.py's `packet_time`, made here from the store's `t` and
 * `t_end`: the frame's end or, for an answer (not of the `mbap` flag), its start plus
 * `char` a byte if that is earlier (nothing is kept per row for it).
 * `base`: the capture's number of the store's first row (a segment's, see
 * sniffer/session/streamed.py; 0 by default), which the transaction ids count from.
 * `blocks` are the rows' blocks in order; `found` how many rows the table gave; `more`
 * False once `rows` is exhausted. */
static PyObject *py_export_rows(PyObject *self, PyObject *args) {
    PyObject *capsule, *store, *rows, *notes, *apart, *bound, *miss;
    int alike;
    unsigned int slow, mode, valued, mbap;
    Py_ssize_t limit, base = 0;
    double char_time;
    if (!PyArg_ParseTuple(args, "OOOO!O!O!pIIIOndI|n", &capsule, &store, &rows, &PyDict_Type,
                          &notes, &PyTuple_Type, &apart, &PyDict_Type, &bound, &alike, &slow,
                          &mode, &valued, &miss, &limit, &char_time, &mbap, &base))
        return NULL;
    if (base < 0) {
        PyErr_SetString(PyExc_ValueError, "export_rows: base is a row number");
        return NULL;
    }
    ExTable *et = PyCapsule_GetPointer(capsule, "modscope.export_table");
    if (et == NULL) return NULL;
    if (et->running) {
        PyErr_SetString(PyExc_RuntimeError, "export_rows: this table is in use");
        return NULL;
    }
    if (!PyIter_Check(rows)) {
        PyErr_SetString(PyExc_TypeError, "export_rows: rows must be an iterator");
        return NULL;
    }
    if (PyTuple_GET_SIZE(apart) < 1) {
        PyErr_SetString(PyExc_TypeError, "export_rows: apart starts with the SunSpec units");
        return NULL;
    }
    for (Py_ssize_t k = 0; k < PyTuple_GET_SIZE(apart); k++) {
        if (!PyDict_Check(PyTuple_GET_ITEM(apart, k))) {
            PyErr_SetString(PyExc_TypeError, "export_rows: apart holds dicts of units");
            return NULL;
        }
    }
    Py_buffer c[ROW_COLUMNS];
    RowColumns rc;
    if (row_columns(store, c, &rc) < 0) return NULL;
    et->running = 1;
    const unsigned char *kind = rc.kind, *channel = rc.channel, *status = rc.status;
    const unsigned char *unit = rc.unit, *fc = rc.fc;
    const uint32_t *flags = rc.flags;
    const double *t_end = rc.t_end, *t_start = rc.t_start;
    const uint64_t *offset = rc.offset;
    const uint16_t *length = rc.length;
    const int32_t *partner = rc.partner;
    Py_ssize_t n = rc.n;
    PyObject *result = NULL, *streams = NULL;
    /* the table's buffers, grown once: a run's blocks go out as bytes of up to about
     * EX_RUN_BYTES, which the allocator gives back and takes again without new pages
     * (far larger runs would fault pages in at every call) */
    Buf out = et->out, exact = et->exact, free_key = et->free_key, packet_key = et->packet_key;
    out.n = 0;
    Py_ssize_t done = 0, found = 0;
    int more = 1;
    streams = PyObject_GetAttrString(store, "streams");
    if (streams == NULL) goto fail;
    if (!PyDict_Check(streams)) {
        PyErr_SetString(PyExc_TypeError, "export_rows: a store's streams are a dict");
        goto fail;
    }
    while (done < limit && out.n < EX_RUN_BYTES) {
        PyObject *item = PyIter_Next(rows);
        if (item == NULL) {
            if (PyErr_Occurred()) goto fail;
            more = 0;
            break;
        }
        done += 1;
        /* the keys made: 1 the exact one, 2 the "F" one, 4 the "W" one, 8 the "N" one
         * (the last two in packet_key) */
        int keyed = 0;
        Py_ssize_t i = PyLong_Check(item) ? PyLong_AsSsize_t(item) : -1;
        if (i == -1 && PyErr_Occurred()) PyErr_Clear(); /* Python says what is wrong */
        if (i < 0 || i >= n) goto slow_path;
        unsigned k = kind[i];
        double t = t_end[i]; /* export.py: packet_time */
        if ((k == K_RESPONSE || k == K_EXCEPTION) && !(flags[i] & mbap)) {
            double start = t_start[i] + (double)length[i] * char_time;
            if (start < t) t = start;
        }
        if (t < 0.0) t = 0.0;
        if (!(t < EX_MAX_TIME)) goto slow_path; /* NaN too */
        if (k == K_EVENT || (flags[i] & slow)) goto slow_path;
        if (PyDict_GET_SIZE(notes)) {
            PyObject *key = PyLong_FromSsize_t(i);
            if (key == NULL) goto fail_item;
            int in = PyDict_Contains(notes, key);
            Py_DECREF(key);
            if (in < 0) goto fail_item;
            if (in) goto slow_path;
        }
        int32_t p = partner[i];
        if (p != -1 && (p < 0 || p >= n)) goto slow_path;
        if (k != K_NOISE) {
            int in = ex_in_any(apart, unit[i]);
            if (in) goto in_or_fail;
            if ((fc[i] & EXCEPTION_BIT) && p != -1) {
                /* an exception its request may explain (describe.py: _explained) */
                if ((in = ex_in(bound, unit[i])) || (in = ex_in(bound, unit[p])) ||
                    (in = ex_in(PyTuple_GET_ITEM(apart, 0), unit[p])))
                    goto in_or_fail;
            }
            goto placed;
        in_or_fail:
            if (in < 0) goto fail_item;
            goto slow_path;
        }
    placed:;
        const char *raw, *asked = NULL;
        Py_ssize_t raw_n, asked_n = 0;
        if (row_bytes(streams, channel, offset, length, i, &raw, &raw_n) < 0) goto fail_item;
        int answer = (k == K_RESPONSE || k == K_EXCEPTION) && p != -1;
        if (answer &&
            row_bytes(streams, channel, offset, length, p, &asked, &asked_n) < 0)
            goto fail_item;
        /* the keys: as Describer.contents makes them, in bytes */
        if (ex_exact_key(&exact, answer, k, flags[i], status[i], raw, raw_n,
                         answer ? flags[p] & mode : 0, asked, asked_n) < 0)
            goto fail_item;
        keyed = 1;
        const unsigned char *r = (const unsigned char *)raw, *q = (const unsigned char *)asked;
        ExSlot *s = ex_slot(et, ex_hash((const unsigned char *)exact.p, exact.n), exact.p,
                            exact.n);
        /* the other keys, made only when the exact one is not found (most rows are) */
        if (s->template == NULL && alike && (k == K_REQUEST || answer) &&
            !((flags[i] | (answer ? flags[p] : 0)) & valued)) {
            int in = ex_in(bound, unit[i]);
            if (in < 0) goto fail_item;
            if (!in && answer && k == K_RESPONSE && unit[i] && raw_n >= 5 &&
                FC_READ_REGISTERS(r[1]) && asked_n >= TABLE_REQUEST_LENGTH && q[1] == r[1] &&
                raw_n == READ_ANSWER_BASE + r[2] &&
                r[2] == 2 * (q[4] << 8 | q[5])) { /* describe.py: _valueless */
                free_key.n = 0;
                if (buf_put(&free_key, "F", 1) < 0 || buf_put(&free_key, raw, 3) < 0 ||
                    ex_put_u16(&free_key, raw_n) < 0 || ex_put_u32(&free_key, flags[i]) < 0 ||
                    ex_put_u8(&free_key, status[i]) < 0 || ex_put_u16(&free_key, asked_n) < 0 ||
                    buf_put(&free_key, asked, asked_n) < 0)
                    goto fail_item;
                keyed |= 2;
                s = ex_slot(et, ex_hash((const unsigned char *)free_key.p, free_key.n),
                            free_key.p, free_key.n);
            }
            if (!in && s->template == NULL) {
                int got = ex_packet_key(&packet_key, k, flags[i], status[i], r, raw_n, q, asked_n);
                if (got < 0) goto fail_item;
                if (got) {
                    keyed |= 4;
                    s = ex_slot(et, ex_hash((const unsigned char *)packet_key.p, packet_key.n),
                                packet_key.p, packet_key.n);
                }
            }
        }
        /* noise: its packet (either style) is its bytes for the `data` dissector and a
         * comment of its problems, which for noise with no note and no MBAP header to
         * read (describe.py: _content, problems.py: frame_problems) say its length, flags
         * and status only: the "N" key, with the bytes put in the template's place */
        if (s->template == NULL && k == K_NOISE && !(flags[i] & F_ENVELOPE_BAD)) {
            packet_key.n = 0;
            if (buf_put(&packet_key, "N", 1) < 0 || ex_put_u32(&packet_key, flags[i]) < 0 ||
                ex_put_u8(&packet_key, status[i]) < 0 || ex_put_u16(&packet_key, raw_n) < 0)
                goto fail_item;
            keyed |= 8;
            s = ex_slot(et, ex_hash((const unsigned char *)packet_key.p, packet_key.n),
                        packet_key.p, packet_key.n);
        }
        if (s->template == NULL) goto slow_path;
        PyObject *tp = s->template;
        PyObject *first = PyTuple_GET_ITEM(tp, 0), *tail = PyTuple_GET_ITEM(tp, 3);
        PyObject *spliced = PyTuple_GET_ITEM(tp, 4);
        int same = (!alike && !(keyed & 8)) ||
                   (PyBytes_GET_SIZE(first) == raw_n &&
                    memcmp(PyBytes_AS_STRING(first), raw, (size_t)raw_n) == 0);
        if (!same && (keyed & 8)) {
            /* the block after its time: the two lengths, then the packet, whose last
             * bytes (before its padding) are the noise's; checked to hold the first's */
            PyObject *middle = PyTuple_GET_ITEM(tp, 2);
            const unsigned char *m = (const unsigned char *)PyBytes_AS_STRING(middle);
            Py_ssize_t mn = PyBytes_GET_SIZE(middle);
            if (tail != Py_None || PyBytes_GET_SIZE(first) != raw_n || mn < 8) goto slow_path;
            Py_ssize_t captured = (Py_ssize_t)m[0] | (Py_ssize_t)m[1] << 8 |
                                  (Py_ssize_t)m[2] << 16 | (Py_ssize_t)m[3] << 24;
            Py_ssize_t at = 8 + captured - raw_n;
            if (at < 8 || at + raw_n > mn ||
                memcmp(m + at, PyBytes_AS_STRING(first), (size_t)raw_n) != 0)
                goto slow_path;
            uint32_t words[2];
            ex_time(t, words);
            if (ex_put_bytes(&out, PyTuple_GET_ITEM(tp, 1)) < 0 || buf_put(&out, words, 8) < 0 ||
                buf_put(&out, m, at) < 0 || buf_put(&out, raw, raw_n) < 0 ||
                buf_put(&out, m + at + raw_n, mn - at - raw_n) < 0)
                goto fail_item;
            found += 1;
            Py_DECREF(item);
            continue;
        }
        /* a splice: the bytes _splice puts in, and the unit, the last byte of the MBAP
         * header before them (the "W" keys leave it out) */
        if (!same && (tail == Py_None || spliced == Py_None || PyBytes_GET_SIZE(first) != raw_n ||
                      PyBytes_GET_SIZE(PyTuple_GET_ITEM(spliced, 0)) != 5))
            goto slow_path;
        uint32_t words[2];
        ex_time(t, words);
        if (ex_put_bytes(&out, PyTuple_GET_ITEM(tp, 1)) < 0 || buf_put(&out, words, 8) < 0 ||
            ex_put_bytes(&out, PyTuple_GET_ITEM(tp, 2)) < 0)
            goto fail_item;
        if (tail != Py_None) {
            size_t tid = (size_t)base + (size_t)(k != K_REQUEST && p != -1 ? p : i);
            unsigned char id[2] = {(unsigned char)((tid >> 8) & 0xFF), (unsigned char)(tid & 0xFF)};
            if (buf_put(&out, id, 2) < 0) goto fail_item;
            if (same) {
                if (ex_put_bytes(&out, tail) < 0) goto fail_item;
            } else if (buf_put(&out, PyBytes_AS_STRING(PyTuple_GET_ITEM(spliced, 0)), 4) < 0 ||
                       buf_put(&out, raw, raw_n - 2) < 0 ||
                       ex_put_bytes(&out, PyTuple_GET_ITEM(spliced, 1)) < 0 ||
                       ex_put_hex(&out, r, raw_n) < 0 ||
                       ex_put_bytes(&out, PyTuple_GET_ITEM(spliced, 2)) < 0 ||
                       ex_put_hex(&out, r + raw_n - 2, 2) < 0 ||
                       ex_put_bytes(&out, PyTuple_GET_ITEM(spliced, 3)) < 0) {
                goto fail_item;
            }
        }
        found += 1;
        Py_DECREF(item);
        continue;
    slow_path: {
        PyObject *got = PyObject_CallOneArg(miss, item);
        Py_DECREF(item);
        if (got == NULL) goto fail;
        PyObject *block, *template;
        if (!PyTuple_CheckExact(got) || PyTuple_GET_SIZE(got) != 2 ||
            !PyBytes_CheckExact(block = PyTuple_GET_ITEM(got, 0))) {
            PyErr_SetString(PyExc_TypeError, "export_rows: miss gives (bytes, template)");
            Py_DECREF(got);
            goto fail;
        }
        template = PyTuple_GET_ITEM(got, 1);
        if (ex_put_bytes(&out, block) < 0) {
            Py_DECREF(got);
            goto fail;
        }
        if (keyed && template != Py_None) {
            if (!ex_template_ok(template)) {
                PyErr_SetString(PyExc_TypeError, "export_rows: not a packet template");
                Py_DECREF(got);
                goto fail;
            }
            if (ex_keep(et, &exact, template) < 0 ||
                ((keyed & 2) && ex_keep(et, &free_key, template) < 0) ||
                ((keyed & 12) && ex_keep(et, &packet_key, template) < 0)) {
                Py_DECREF(got);
                goto fail;
            }
        }
        Py_DECREF(got);
        continue;
    }
    fail_item:
        Py_DECREF(item);
        goto fail;
    }
    {
        PyObject *blocks = buf_bytes(&out);
        if (blocks != NULL) {
            result = Py_BuildValue("(NnnO)", blocks, done, found, more ? Py_True : Py_False);
        }
    }
    goto done_;
fail:
    Py_CLEAR(result);
done_:
    et->running = 0;
    et->out = out;
    et->exact = exact;
    et->free_key = free_key;
    et->packet_key = packet_key;
    Py_XDECREF(streams);
    release_all(c, ROW_COLUMNS);
    return result;
}

/* export_moved(store, char, apart, mbap[, last]) -> (moved, last): the largest move of
 * export.py's exported_timing: over the rows of the store's columns, in order (events,
 * rows of the `mbap` flag and rows of no bytes left out), each frame read back from its
 * packet (`packet_time`, as export_rows makes it) starts `char` a byte before it, and at
 * least `apart` after the end of the frame before; a request's end moves by the
 * difference to its `t_end`, any other frame's start (but noise's) to its `t`. `moved`
 * is the largest such move, in seconds, as the Python loop (_largest_move) finds it
 * (max keeps the first of equals, as there); `last` the end of the last frame as read
 * back (None: no frame). The `last` given is that of the frame before the store's first
 * row (None, the default: none), so that a capture's segments, taken in turn, give the
 * moves of one store of every row. */
static PyObject *py_export_moved(PyObject *self, PyObject *args) {
    PyObject *store, *before = Py_None;
    double char_time, apart;
    unsigned int mbap;
    if (!PyArg_ParseTuple(args, "OddI|O", &store, &char_time, &apart, &mbap, &before))
        return NULL;
    double last = 0.0;
    int have_last = before != Py_None;
    if (have_last) {
        last = PyFloat_AsDouble(before);
        if (last == -1.0 && PyErr_Occurred()) return NULL;
    }
    static const ColSpec specs[] = {
        {"kind", 'B', 0}, {"flags", 'I', 0}, {"t", 'd', 0}, {"t_end", 'd', 0}, {"length", 'H', 0},
    };
    Py_buffer c[5];
    if (columns(store, specs, 5, c) < 0) return NULL;
    const unsigned char *kind = c[0].buf;
    const uint32_t *flags = c[1].buf;
    const double *t = c[2].buf, *t_end = c[3].buf;
    const uint16_t *length = c[4].buf;
    Py_ssize_t n = c[2].len / 8;
    if (c[4].len / 2 != n) { /* zip(strict=True) over t and length */
        release_all(c, 5);
        PyErr_SetString(PyExc_ValueError, "export_moved: the store's t and length differ");
        return NULL;
    }
    if (c[0].len < n || c[1].len / 4 < n || c[3].len / 8 < n) {
        release_all(c, 5);
        PyErr_SetString(PyExc_IndexError, "export_moved: a column is short");
        return NULL;
    }
    double moved = 0.0;
    for (Py_ssize_t i = 0; i < n; i++) {
        unsigned k = kind[i];
        Py_ssize_t size = length[i];
        if (k == K_EVENT || (flags[i] & mbap) || !size) continue;
        double at = t_end[i];
        if (k == K_RESPONSE || k == K_EXCEPTION) {
            double begin = t[i] + (double)size * char_time;
            if (begin < at) at = begin;
        }
        double start = at - (double)size * char_time;
        if (have_last && last + apart > start) start = last + apart;
        last = start > at ? start : at;
        have_last = 1;
        double move;
        if (k == K_REQUEST)
            move = fabs(last - t_end[i]);
        else if (k != K_NOISE)
            move = fabs(start - t[i]);
        else
            continue;
        if (move > moved) moved = move;
    }
    release_all(c, 5);
    if (!have_last) return Py_BuildValue("(dO)", moved, Py_None);
    return Py_BuildValue("(dd)", moved, last);
}

/* ---- the text and JSONL listings' lines ------------------------------------------------- */

/* listing_table() -> a table of the content keys one Lister met (sniffer/outputs/listing.py:
 * Lister.write), each with the parts Python made for its content's lines: the export's
 * table (ExTable, ex_slot, ex_keep), with the listings' own keys, and the latencies'
 * texts a text listing showed (Latencies.text), by value. */
#define LS_LAT_SLOTS 8192
#define LS_LAT_MAX 4096 /* as Latencies.text keeps them */
#define LS_RUN_BYTES (1 << 18)

typedef struct {
    uint64_t bits; /* the value's bits (only values > 0 are kept, as Latencies.text) */
    int bound;
    PyObject *text; /* NULL: an empty slot */
} LsLat;

typedef struct {
    ExTable keys;
    LsLat *lat;
    Py_ssize_t lat_used;
} LsTable;

static void ls_table_free(PyObject *capsule) {
    LsTable *lt = PyCapsule_GetPointer(capsule, "modscope.listing_table");
    if (lt == NULL) return;
    ExTable *et = &lt->keys;
    if (et->slots != NULL) ex_clear(et);
    PyMem_Free(et->slots);
    buf_free(&et->arena);
    buf_free(&et->out);
    buf_free(&et->exact);
    buf_free(&et->free_key);
    buf_free(&et->packet_key);
    if (lt->lat != NULL)
        for (Py_ssize_t k = 0; k < LS_LAT_SLOTS; k++) Py_CLEAR(lt->lat[k].text);
    PyMem_Free(lt->lat);
    PyMem_Free(lt);
}

static PyObject *py_listing_table(PyObject *self, PyObject *unused) {
    LsTable *lt = PyMem_Calloc(1, sizeof(LsTable));
    if (lt == NULL) return PyErr_NoMemory();
    if (ex_init(&lt->keys) < 0) {
        PyMem_Free(lt);
        return NULL;
    }
    lt->lat = PyMem_Calloc(LS_LAT_SLOTS, sizeof(LsLat));
    if (lt->keys.slots == NULL || lt->lat == NULL) {
        PyMem_Free(lt->keys.slots);
        PyMem_Free(lt->lat);
        PyMem_Free(lt);
        return PyErr_NoMemory();
    }
    PyObject *capsule = PyCapsule_New(lt, "modscope.listing_table", ls_table_free);
    if (capsule == NULL) {
        PyMem_Free(lt->keys.slots);
        PyMem_Free(lt->lat);
        PyMem_Free(lt);
    }
    return capsule;
}

/* `round(x, nd)` as CPython's float.__round__ makes it for a finite x: the digits of
 * the correctly rounded fixed format (the same _Py_dg_dtoa mode 3 digits), read back by
 * the same correctly rounding strtod. 0, or -1 with an exception set. */
static int ls_round(double x, int nd, double *out) {
    char *s = PyOS_double_to_string(x, 'f', nd, 0, NULL);
    if (s == NULL) return -1;
    double r = PyOS_string_to_double(s, NULL, NULL);
    PyMem_Free(s);
    if (r == -1.0 && PyErr_Occurred()) return -1;
    *out = r;
    return 0;
}

/* round(|x| * 10**nd) to the nearest integer, ties to even, exactly (from x's binary
 * value, as the correctly rounded formats and round() take it): 1 with it in *k when it
 * is below 2**52, else 0 (not finite, or too large: the slow path formats it). nd <= 9. */
static const double LS_POW10[10] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};
static const uint64_t LS_IPOW10[10] = {1ull,      10ull,      100ull,      1000ull,      10000ull,
                                       100000ull, 1000000ull, 10000000ull, 100000000ull,
                                       1000000000ull};
#define LS_EXACT (1ull << 52)

static int ls_scaled(double x, int nd, uint64_t *k) {
    double a = fabs(x);
    if (!(a < 4503599627370496.0) || nd < 0 || nd > 9) return 0; /* 2**52; NaN too */
    if (a == 0.0) {
        *k = 0;
        return 1;
    }
    int e;
    double f = frexp(a, &e);              /* a = f * 2**e, 0.5 <= f < 1 */
    uint64_t m = (uint64_t)ldexp(f, 53); /* a = m * 2**(e - 53), exactly */
    int shift = 53 - e;                   /* > 0: a < 2**52 */
    if (shift >= 120) {                   /* a * 10**9 < 2**-60: rounds to 0 */
        *k = 0;
        return 1;
    }
    unsigned __int128 p = (unsigned __int128)m * LS_IPOW10[nd];
    unsigned __int128 q = p >> shift, r = p - (q << shift);
    unsigned __int128 half = (unsigned __int128)1 << (shift - 1);
    if (r > half || (r == half && (q & 1))) q += 1;
    if (q >= LS_EXACT) return 0;
    *k = (uint64_t)q;
    return 1;
}

/* `round(x, nd)`: from ls_scaled's integer, k / 10**nd, one correctly rounded division of
 * two exact doubles, which is the double nearest the decimal (what round() reads back),
 * signed as x (round(-1e-9, 6) is -0.0); the slow path where ls_scaled gives none. */
static int ls_round_fast(double x, int nd, double *out) {
    uint64_t k;
    if (!ls_scaled(x, nd, &k)) return ls_round(x, nd, out);
    double v = (double)k / LS_POW10[nd];
    *out = signbit(x) ? -v : v;
    return 0;
}

/* The digits of k / 10**nd (`%.{nd}f` of x, k from ls_scaled), signed, into b; with
 * `shortest`, trailing zeros of the fraction dropped but one. */
static int ls_put_fixed(Buf *b, int negative, uint64_t k, int nd, int shortest) {
    char text[48];
    int w = 0;
    if (negative) text[w++] = '-';
    uint64_t whole = k / LS_IPOW10[nd], frac = k % LS_IPOW10[nd];
    w += snprintf(text + w, sizeof text - (size_t)w, "%llu", (unsigned long long)whole);
    if (nd || shortest) text[w++] = '.';
    char digits[10];
    for (int d = nd - 1; d >= 0; d--) {
        digits[d] = (char)('0' + frac % 10);
        frac /= 10;
    }
    int used = nd;
    if (shortest)
        while (used > 1 && digits[used - 1] == '0') used--;
    if (!nd && shortest) digits[used++] = '0';
    memcpy(text + w, digits, (size_t)used);
    w += used;
    return buf_put(b, text, w);
}

/* `repr(x)` (what json.dumps writes of a finite float) into b. */
static int ls_put_repr(Buf *b, double x) {
    char *s = PyOS_double_to_string(x, 'r', 0, Py_DTSF_ADD_DOT_0, NULL);
    if (s == NULL) return -1;
    int r = buf_put(b, s, (Py_ssize_t)strlen(s));
    PyMem_Free(s);
    return r;
}

/* `repr(round(x, nd))`, x finite. Where ls_scaled gives k and the value is 0 or at least
 * 1e-4 (repr's fixed notation), it is k's digits, the shortest: the decimal D = k / 10**nd
 * is what round() reads back, and, as k < 2**52, the doubles about D are closer together
 * than 10**-nd, so that no other multiple of 10**-nd, nor any decimal of fewer digits (each
 * such a multiple), reads back as the same double: repr's shortest digits are D's. */
static int ls_put_rounded(Buf *b, double x, int nd) {
    uint64_t k;
    if (ls_scaled(x, nd, &k) && (k == 0 || nd < 4 || k >= LS_IPOW10[nd - 4]))
        return ls_put_fixed(b, signbit(x) != 0, k, nd, 1);
    double r;
    if (ls_round(x, nd, &r) < 0) return -1;
    return ls_put_repr(b, r);
}

/* `f"{x:12.{nd}f}"` into b. */
static int ls_put_time(Buf *b, double x, int nd) {
    uint64_t k;
    Buf one = {NULL, 0, 0};
    char *slow = NULL;
    const char *text;
    Py_ssize_t n;
    if (ls_scaled(x, nd, &k)) {
        char room[48];
        one.p = room;
        one.cap = sizeof room;
        if (ls_put_fixed(&one, signbit(x) != 0, k, nd, 0) < 0) return -1;
        text = one.p;
        n = one.n;
    } else {
        slow = PyOS_double_to_string(x, 'f', nd, 0, NULL);
        if (slow == NULL) return -1;
        text = slow;
        n = (Py_ssize_t)strlen(slow);
    }
    int bad = 0;
    for (Py_ssize_t pad = n; pad < 12 && !bad; pad++) bad = buf_put(b, " ", 1) < 0;
    bad = bad || buf_put(b, text, n) < 0;
    PyMem_Free(slow);
    return bad ? -1 : 0;
}

/* listing_floats(x, nd) -> (round(x, nd), repr(round(x, nd)), f"{x:12.{nd}f}") as
 * listing_rows makes them: for tests/outputs/test_listing_compiled.py, which holds them to
 * Python's. */
static PyObject *py_listing_floats(PyObject *self, PyObject *args) {
    double x, r;
    int nd;
    if (!PyArg_ParseTuple(args, "di", &x, &nd)) return NULL;
    if (!isfinite(x) || nd < 0 || nd > 9) {
        PyErr_SetString(PyExc_ValueError, "listing_floats: a finite x, 0 <= nd <= 9");
        return NULL;
    }
    Buf a = {NULL, 0, 0}, b = {NULL, 0, 0};
    PyObject *result = NULL;
    if (ls_round_fast(x, nd, &r) == 0 && ls_put_rounded(&a, x, nd) == 0 &&
        ls_put_time(&b, x, nd) == 0)
        result = Py_BuildValue("(ds#s#)", r, a.p, a.n, b.p, b.n);
    buf_free(&a);
    buf_free(&b);
    return result;
}

/* `str(v)`; by hand, as a splice writes up to 125 of them a row (snprintf's parsing of its
 * format cost more than the digits). */
static int ls_put_int(Buf *b, long long v) {
    char text[24];
    int w = sizeof text;
    unsigned long long u = v < 0 ? 0ull - (unsigned long long)v : (unsigned long long)v;
    do {
        text[--w] = (char)('0' + u % 10);
        u /= 10;
    } while (u);
    if (v < 0) text[--w] = '-';
    return buf_put(b, text + w, (Py_ssize_t)sizeof text - w);
}

static int ls_put_str(Buf *b, PyObject *s) {
    Py_ssize_t n;
    const char *p = PyUnicode_AsUTF8AndSize(s, &n);
    if (p == NULL) return -1;
    return buf_put(b, p, n);
}

/* `raw.hex()`: no separator. */
static int ls_put_hex(Buf *b, const unsigned char *p, Py_ssize_t n) {
    static const char digits[] = "0123456789abcdef";
    if (b->n + 2 * n > b->cap && buf_grow(b, 2 * n) < 0) return -1;
    char *w = b->p + b->n;
    for (Py_ssize_t k = 0; k < n; k++) {
        *w++ = digits[p[k] >> 4];
        *w++ = digits[p[k] & 15];
    }
    b->n += 2 * n;
    return 0;
}

/* The latency parameters Latencies._settle gives a store's stamps and resolution: the
 * step shown, its digits, the least value measured (RESOLVED resolutions) and the
 * resolution. */
typedef struct {
    double step, least, resolution;
    int digits;
} LsLatency;

/* Latencies.ms for stamps that are neither none nor print times: 1 with the value in ms
 * and whether it is a bound, 0 for none, -1 with an exception set. `t` is the answer's
 * start, `end` the request's end, both finite. */
static int ls_latency(const LsLatency *lp, double t, double end, double *ms, int *bound) {
    double raw = t - end;
    if (!(raw < lp->least)) {
        double a, b;
        if (ls_round_fast(t, 6, &a) < 0 || ls_round_fast(end, 6, &b) < 0) return -1;
        double value = a - b;
        if (value == value) value = nearbyint(value / lp->step) * lp->step; /* half even */
        *bound = 0;
        return ls_round_fast(value * 1000, lp->digits, ms) < 0 ? -1 : 1;
    }
    double res = lp->resolution;
    if (res > 0 && raw + res > 0) {
        double up = ceil((raw + res) / lp->step - 1e-9) * lp->step * 1000;
        *bound = 1;
        return ls_round_fast(up, lp->digits, ms) < 0 ? -1 : 1;
    }
    return 0;
}

/* The text a text line shows of latency (ms, bound) (Latencies.text): kept by value
 * once `text(ms, bound)` gave it, as Latencies.text keeps it (values > 0, at most
 * LS_LAT_MAX). A borrowed or new reference in *out: *owned says which. */
static int ls_lat_text(LsTable *lt, PyObject *text, double ms, int bound, PyObject **out,
                       int *owned) {
    uint64_t bits;
    memcpy(&bits, &ms, 8);
    int keep = ms > 0;
    LsLat *s = NULL;
    if (keep) {
        Py_ssize_t k = (Py_ssize_t)((bits ^ (bits >> 29) ^ (uint64_t)bound) * 0x9E3779B97F4A7C15ull >> 51) &
                       (LS_LAT_SLOTS - 1);
        for (;;) {
            s = &lt->lat[k];
            if (s->text == NULL) break;
            if (s->bits == bits && s->bound == bound) {
                *out = s->text;
                *owned = 0;
                return 0;
            }
            k = (k + 1) & (LS_LAT_SLOTS - 1);
        }
    }
    PyObject *got = PyObject_CallFunction(text, "dO", ms, bound ? Py_True : Py_False);
    if (got == NULL) return -1;
    if (!PyUnicode_Check(got)) {
        Py_DECREF(got);
        PyErr_SetString(PyExc_TypeError, "listing_rows: a latency's text is a str");
        return -1;
    }
    if (keep && lt->lat_used < LS_LAT_MAX) {
        s->bits = bits;
        s->bound = bound;
        Py_INCREF(got);
        s->text = got;
        lt->lat_used += 1;
    }
    *out = got;
    *owned = 1;
    return 0;
}

/* Whether `r`, `rn` bytes of an RTU frame of function `code`, is a well-formed FC 5 or
 * 6 write or echo (describe.py: _single_write): 8 bytes, its code `code`, and for FC 5 a
 * coil value of ON (0xFF00) or OFF (0x0000). */
static int ls_single_write(unsigned code, const unsigned char *r, Py_ssize_t rn) {
    return FC_WRITE_SINGLE(code) && rn == TABLE_REQUEST_LENGTH && r[1] == code &&
           (!FC_WRITE_COIL(code) || ((r[4] == 0xFF || r[4] == 0) && r[5] == 0));
}

/* The listings' keys of a row besides the exact one (Describer.contents with values
 * False and writes True, describe.py), each with what its Python key holds and more
 * (the code, and all the row's flags): "F" an FC 3/4 answer (_valueless), "B" an FC 1/2
 * answer and its padding bits (_bits_valueless), "R" an FC 15/16 answer echoing its
 * write (_written, _write_key), "Q" an FC 15/16 write (_write_request, _write_key), "W"
 * an FC 5/6 write and "C" its echo of the same bytes (_single_write: their unit, code
 * and address). Made for an RTU row of a unit other than 0 with no dictionary and none
 * of the VALUED_FLAGS (nor, for an answer, its request), as Python makes its. 1: made;
 * 0: none; -1: no memory. */
static int ls_free_key(Buf *w, unsigned k, unsigned code, uint32_t fl, unsigned st,
                       const unsigned char *r, Py_ssize_t rn, const unsigned char *q,
                       Py_ssize_t qn) {
    w->n = 0;
    if (ls_single_write(code, r, rn)) {
        /* a write, or an answer that is its request's bytes (not an exception: its code
         * has the bit set) */
        int echo = k == K_RESPONSE && q != NULL && qn == rn && memcmp(r, q, (size_t)rn) == 0;
        if (k != K_REQUEST && !echo) return 0;
        if (buf_put(w, echo ? "C" : "W", 1) < 0 || ex_put_u8(w, code) < 0 ||
            ex_put_u32(w, fl) < 0 || ex_put_u8(w, st) < 0 || buf_put(w, r, 4) < 0)
            return -1;
        return 1;
    }
    if (k == K_REQUEST) {
        if (!FC_WRITE_MULTIPLE(code) || rn < 9 || !FC_WRITE_MULTIPLE(r[1])) return 0;
        Py_ssize_t quantity = r[4] << 8 | r[5];
        Py_ssize_t need = r[1] == 15 ? (quantity + 7) / 8 : 2 * quantity;
        if (rn != 9 + r[6] || r[6] != need) return 0;
        unsigned used = (unsigned)(quantity % 8);
        unsigned padding = r[1] == 15 && used ? r[rn - 3] & (0xFFu << used) & 0xFFu : 0;
        if (buf_put(w, "Q", 1) < 0 || ex_put_u8(w, code) < 0 || ex_put_u32(w, fl) < 0 ||
            ex_put_u8(w, st) < 0 || buf_put(w, r, 7) < 0 || ex_put_u16(w, rn) < 0 ||
            ex_put_u8(w, padding) < 0)
            return -1;
        return 1;
    }
    if (k != K_RESPONSE || q == NULL) return 0;
    if (FC_READ_REGISTERS(code)) {
        if (!(rn >= 5 && FC_READ_REGISTERS(r[1]) && qn >= 8 && q[1] == r[1] &&
              rn == 5 + r[2] && r[2] == 2 * (q[4] << 8 | q[5])))
            return 0;
        if (buf_put(w, "F", 1) < 0 || ex_put_u8(w, code) < 0 || buf_put(w, r, 3) < 0 ||
            ex_put_u16(w, rn) < 0 || ex_put_u32(w, fl) < 0 || ex_put_u8(w, st) < 0 ||
            ex_put_u16(w, qn) < 0 || buf_put(w, q, qn) < 0)
            return -1;
        return 1;
    }
    if (FC_WRITE_MULTIPLE(code)) {
        if (rn != 8 || !FC_WRITE_MULTIPLE(r[1]) || qn < 9 || memcmp(r, q, 6) != 0) return 0;
        Py_ssize_t quantity = q[4] << 8 | q[5];
        Py_ssize_t need = r[1] == 15 ? (quantity + 7) / 8 : 2 * quantity;
        if (qn != 9 + q[6] || q[6] != need) return 0;
        unsigned used = (unsigned)(quantity % 8);
        unsigned padding = q[1] == 15 && used ? q[qn - 3] & (0xFFu << used) & 0xFFu : 0;
        if (buf_put(w, "R", 1) < 0 || ex_put_u8(w, code) < 0 || ex_put_u32(w, fl) < 0 ||
            ex_put_u8(w, st) < 0 || buf_put(w, r, rn) < 0 || buf_put(w, q, 7) < 0 ||
            ex_put_u16(w, qn) < 0 || ex_put_u8(w, padding) < 0)
            return -1;
        return 1;
    }
    if (FC_READ_BITS(code)) {
        if (rn < 6 || !FC_READ_BITS(r[1]) || qn < 8 || q[1] != r[1]) return 0;
        Py_ssize_t quantity = q[4] << 8 | q[5];
        if (!quantity || rn != 5 + r[2] || r[2] != (quantity + 7) / 8) return 0;
        unsigned used = (unsigned)(quantity % 8);
        unsigned padding = used ? r[rn - 3] & (0xFFu << used) & 0xFFu : 0;
        if (buf_put(w, "B", 1) < 0 || ex_put_u8(w, code) < 0 || buf_put(w, r, 3) < 0 ||
            ex_put_u16(w, rn) < 0 || ex_put_u32(w, fl) < 0 || ex_put_u8(w, st) < 0 ||
            ex_put_u16(w, qn) < 0 || buf_put(w, q, qn) < 0 || ex_put_u8(w, padding) < 0)
            return -1;
        return 1;
    }
    return 0;
}

/* A template as listing.py's _template makes it, checked once when it is kept: text
 * (head, tail, whole, raw, timed, single), single None or _text_spliced's tuple (empty,
 * or what comes before and after the value said); JSONL (first, second, registers,
 * spliced, raw, timed), spliced None, (after_hex, before_values, after_text, at, count,
 * words) as _spliced makes it, or _Single's four parts (after_hex, before_said,
 * before_number, after_text). */
static int ls_template_ok(PyObject *t, int json) {
    if (!PyTuple_CheckExact(t) || PyTuple_GET_SIZE(t) != 6) return 0;
    for (int k = 0; k < 3; k++)
        if (!PyUnicode_CheckExact(PyTuple_GET_ITEM(t, k))) return 0;
    if (!PyBool_Check(PyTuple_GET_ITEM(t, json ? 5 : 4))) return 0;
    if (!PyBytes_CheckExact(PyTuple_GET_ITEM(t, json ? 4 : 3))) return 0;
    PyObject *sp = PyTuple_GET_ITEM(t, json ? 3 : 5);
    if (sp == Py_None) return 1;
    if (!PyTuple_CheckExact(sp)) return 0;
    Py_ssize_t size = PyTuple_GET_SIZE(sp);
    if (size != (json ? 4 : 2) && !(json ? size == 6 : size == 0)) return 0;
    for (Py_ssize_t k = 0; k < (size == 6 ? 3 : size); k++)
        if (!PyUnicode_CheckExact(PyTuple_GET_ITEM(sp, k))) return 0;
    if (size != 6) return 1;
    return PyLong_CheckExact(PyTuple_GET_ITEM(sp, 3)) && PyLong_CheckExact(PyTuple_GET_ITEM(sp, 4)) &&
           PyBool_Check(PyTuple_GET_ITEM(sp, 5));
}

/* How the text of `r`, the 8 bytes of an RTU FC 5 or 6 write or echo, says its value
 * (listing.py: _said), into `said`: `0x1234` for a register, `ON` or `OFF` for a coil.
 * Its length; 0 for none (another coil value, another code or length). */
static int ls_said(char said[6], const unsigned char *r, Py_ssize_t rn) {
    static const char upper[] = "0123456789ABCDEF";
    if (rn != TABLE_REQUEST_LENGTH || !FC_WRITE_SINGLE(r[1])) return 0;
    if (!FC_WRITE_COIL(r[1])) {
        const char text[6] = {'0', 'x', upper[r[4] >> 4], upper[r[4] & 15], upper[r[5] >> 4],
                              upper[r[5] & 15]};
        memcpy(said, text, 6);
        return 6;
    }
    if (r[5] != 0 || (r[4] != 0xFF && r[4] != 0)) return 0;
    memcpy(said, r[4] ? "ON" : "OFF", r[4] ? 2 : 3);
    return r[4] ? 2 : 3;
}

/* The JSONL parts of `r`, a row whose content's parts were made from other bytes of the
 * same length, as listing.py's _splice makes them into `first` and `second`: its values,
 * from byte `at`, `count` big-endian words or bits, first bit first (`sp` _spliced's
 * tuple); or, for an FC 5 or 6 write (`sp` _Single's parts), its value as the summary
 * says it, its number and its text. 1: made; 0: the spliced parts do not fit these bytes
 * (Python makes the line); -1: an error. */
static int ls_splice(Buf *first, Buf *second, PyObject *sp, const unsigned char *r, Py_ssize_t rn) {
    first->n = second->n = 0;
    if (PyTuple_GET_SIZE(sp) == 4) {
        char said[6];
        int n = ls_said(said, r, rn);
        if (!n) return 0;
        if (buf_put(first, "\"raw\": \"", 8) < 0 || ls_put_hex(first, r, rn) < 0 ||
            ls_put_str(first, PyTuple_GET_ITEM(sp, 0)) < 0 ||
            ls_put_str(second, PyTuple_GET_ITEM(sp, 1)) < 0 || buf_put(second, said, n) < 0 ||
            ls_put_str(second, PyTuple_GET_ITEM(sp, 2)) < 0 ||
            ls_put_int(second, r[4] << 8 | r[5]) < 0 ||
            buf_put(second, ", \"text\": \"", 11) < 0 || buf_put(second, said, n) < 0 ||
            ls_put_str(second, PyTuple_GET_ITEM(sp, 3)) < 0)
            return -1;
        return 1;
    }
    Py_ssize_t at = PyLong_AsSsize_t(PyTuple_GET_ITEM(sp, 3));
    Py_ssize_t count = PyLong_AsSsize_t(PyTuple_GET_ITEM(sp, 4));
    if ((at == -1 || count == -1) && PyErr_Occurred()) return -1;
    int words = PyTuple_GET_ITEM(sp, 5) == Py_True;
    Py_ssize_t size = words ? 2 * count : (count + 7) / 8;
    if (count <= 0 || (words && count >= 128) || at < 0 || at + size != rn - 2) return 0;
    if (buf_put(first, "\"raw\": \"", 8) < 0 || ls_put_hex(first, r, rn) < 0 ||
        ls_put_str(first, PyTuple_GET_ITEM(sp, 0)) < 0 ||
        ls_put_str(second, PyTuple_GET_ITEM(sp, 1)) < 0 ||
        buf_put(second, "{\"name\": \"values\", \"value\": [", 29) < 0)
        return -1;
    const unsigned char *d = r + at;
    if (words) {
        for (Py_ssize_t k = 0; k < count; k++) {
            if ((k && buf_put(second, ", ", 2) < 0) || ls_put_int(second, d[2 * k] << 8 | d[2 * k + 1]) < 0)
                return -1;
        }
        if (buf_put(second, "], \"text\": \"", 12) < 0) return -1;
        static const char upper[] = "0123456789ABCDEF";
        for (Py_ssize_t k = 0; k < count; k++) {
            const unsigned char *h = d + 2 * k;
            char text[7] = {' ', '0', 'x', upper[h[0] >> 4], upper[h[0] & 15], upper[h[1] >> 4],
                            upper[h[1] & 15]};
            if (buf_put(second, k ? text : text + 1, k ? 7 : 6) < 0) return -1;
        }
    } else {
        for (int pass = 0; pass < 2; pass++) {
            for (Py_ssize_t k = 0; k < count; k++) {
                char bit = (d[k / 8] >> (k % 8)) & 1 ? '1' : '0';
                if ((k && buf_put(second, pass ? " " : ", ", pass ? 1 : 2) < 0) ||
                    buf_put(second, &bit, 1) < 0)
                    return -1;
            }
            if (!pass && buf_put(second, "], \"text\": \"", 12) < 0) return -1;
        }
    }
    if (ls_put_str(second, PyTuple_GET_ITEM(sp, 2)) < 0) return -1;
    return 1;
}

/* listing_rows(table, store, rows, notes, apart, bound, links, slow, mode, valued, miss,
 *              limit, origin, json, latency, text, statuses, timing) -> (lines, rows, found, more)
 * Lister.write's loop (sniffer/outputs/listing.py) over up to `limit` rows taken from the
 * iterator `rows`, for a text (`json` false) or JSONL listing with no peers, relative
 * times and no numbering: the lines of the rows whose content key `table` holds, made
 * from the parts Python kept for it as Lister._text_line and _json_line make them (the
 * time `%12.6f` from `origin`, `round` and `repr` of the JSONL times, the latency as
 * Latencies.ms gives it, the transaction, and, for a JSONL row of other values than its
 * content's first row, its bytes and values spliced in as _splice does). Every other row
 * is handed to `miss(row)`, which returns (its line, the template of its content or
 * None), kept under the row's keys: the exact one (the export's: the row's bytes, kind,
 * flags, status and its request's bytes and mode) and, where Describer.contents would
 * look one up, the listings' shape key (ls_free_key). A row Describer.contents gives no
 * content (an event, a row with a note, a unit of `apart`, an exception its request may
 * explain), a slow answer (`slow`), a JSONL row of `links` and a row whose latency the
 * parameters `latency` (step, least, digits, resolution; None: Python measures) cannot
 * give are always missed. `text(ms, bound)`: a latency's text (Latencies.text);
 * `statuses`: the JSON of each status; `timing`: what every JSONL line ends with.
 * `lines` is the rows' lines, each with its newline; `found` how many the table gave. */
static PyObject *py_listing_rows(PyObject *self, PyObject *args) {
    PyObject *capsule, *store, *rows, *notes, *apart, *bound, *links, *miss, *latency, *text,
        *statuses, *timing;
    int json;
    unsigned int slow, mode, valued;
    Py_ssize_t limit, base;
    double origin;
    if (!PyArg_ParseTuple(args, "OOOO!O!O!O!IIIOndpOOO!Un", &capsule, &store, &rows,
                          &PyDict_Type, &notes, &PyTuple_Type, &apart, &PyDict_Type, &bound,
                          &PyDict_Type, &links, &slow, &mode, &valued, &miss, &limit, &origin,
                          &json, &latency, &text, &PyTuple_Type, &statuses, &timing, &base))
        return NULL;
    LsTable *lt = PyCapsule_GetPointer(capsule, "modscope.listing_table");
    if (lt == NULL) return NULL;
    ExTable *et = &lt->keys;
    if (et->running) {
        PyErr_SetString(PyExc_RuntimeError, "listing_rows: this table is in use");
        return NULL;
    }
    if (!PyIter_Check(rows)) {
        PyErr_SetString(PyExc_TypeError, "listing_rows: rows must be an iterator");
        return NULL;
    }
    if (PyTuple_GET_SIZE(apart) < 1) {
        PyErr_SetString(PyExc_TypeError, "listing_rows: apart starts with the SunSpec units");
        return NULL;
    }
    for (Py_ssize_t k = 0; k < PyTuple_GET_SIZE(apart); k++) {
        if (!PyDict_Check(PyTuple_GET_ITEM(apart, k))) {
            PyErr_SetString(PyExc_TypeError, "listing_rows: apart holds dicts of units");
            return NULL;
        }
    }
    for (Py_ssize_t k = 0; k < PyTuple_GET_SIZE(statuses); k++) {
        if (!PyUnicode_Check(PyTuple_GET_ITEM(statuses, k))) {
            PyErr_SetString(PyExc_TypeError, "listing_rows: statuses are str");
            return NULL;
        }
    }
    LsLatency lp = {0.0, 0.0, 0.0, 0};
    int measured = latency != Py_None;
    if (measured &&
        !PyArg_ParseTuple(latency, "ddid", &lp.step, &lp.least, &lp.digits, &lp.resolution))
        return NULL;
    if (!(origin == origin) || !isfinite(origin)) {
        PyErr_SetString(PyExc_ValueError, "listing_rows: the origin is not finite");
        return NULL;
    }
    Py_buffer c[ROW_COLUMNS];
    RowColumns rc;
    if (row_columns(store, c, &rc) < 0) return NULL;
    et->running = 1;
    const unsigned char *kind = rc.kind, *channel = rc.channel, *status = rc.status;
    const unsigned char *unit = rc.unit, *fc = rc.fc;
    const uint32_t *flags = rc.flags;
    const double *t_end = rc.t_end, *t_start = rc.t_start;
    const uint64_t *offset = rc.offset;
    const uint16_t *length = rc.length;
    const int32_t *partner = rc.partner;
    Py_ssize_t n = rc.n;
    PyObject *result = NULL, *streams = NULL;
    /* out: the lines; exact, free_key: the keys; packet_key: a splice's second part */
    Buf out = et->out, exact = et->exact, free_key = et->free_key, spliced = et->packet_key;
    Buf first = {NULL, 0, 0};
    out.n = 0;
    Py_ssize_t done = 0, found = 0;
    int more = 1;
    streams = PyObject_GetAttrString(store, "streams");
    if (streams == NULL) goto fail;
    if (!PyDict_Check(streams)) {
        PyErr_SetString(PyExc_TypeError, "listing_rows: a store's streams are a dict");
        goto fail;
    }
    while (done < limit && out.n < LS_RUN_BYTES) {
        PyObject *item = PyIter_Next(rows);
        if (item == NULL) {
            if (PyErr_Occurred()) goto fail;
            more = 0;
            break;
        }
        done += 1;
        Py_ssize_t line_at = out.n, last_n = 0;
        int keyed = 0; /* 1: the exact key made, 2: the shape key too */
        Py_ssize_t i = PyLong_Check(item) ? PyLong_AsSsize_t(item) : -1;
        if (i == -1 && PyErr_Occurred()) PyErr_Clear(); /* Python says what is wrong */
        if (i < 0 || i >= n) goto slow_path;
        unsigned k = kind[i];
        if (k == K_EVENT || (flags[i] & slow)) goto slow_path;
        if (!isfinite(t_start[i]) || !isfinite(t_end[i])) goto slow_path;
        if (PyDict_GET_SIZE(notes) || (json && PyDict_GET_SIZE(links))) {
            PyObject *key = PyLong_FromSsize_t(i);
            if (key == NULL) goto fail_item;
            int in = PyDict_GET_SIZE(notes) ? PyDict_Contains(notes, key) : 0;
            if (!in && json && PyDict_GET_SIZE(links)) in = PyDict_Contains(links, key);
            Py_DECREF(key);
            if (in < 0) goto fail_item;
            if (in) goto slow_path;
        }
        int32_t p = partner[i];
        if (p != -1 && (p < 0 || p >= n)) goto slow_path;
        if (k != K_NOISE) {
            int in = ex_in_any(apart, unit[i]);
            if (in) goto in_or_fail;
            if ((fc[i] & EXCEPTION_BIT) && p != -1) {
                /* an exception its request may explain (describe.py: _explained) */
                if ((in = ex_in(bound, unit[i])) || (in = ex_in(bound, unit[p])) ||
                    (in = ex_in(PyTuple_GET_ITEM(apart, 0), unit[p])))
                    goto in_or_fail;
            }
            goto placed;
        in_or_fail:
            if (in < 0) goto fail_item;
            goto slow_path;
        }
    placed:;
        const char *raw, *asked = NULL;
        Py_ssize_t raw_n, asked_n = 0;
        if (row_bytes(streams, channel, offset, length, i, &raw, &raw_n) < 0) goto fail_item;
        int answer = (k == K_RESPONSE || k == K_EXCEPTION) && p != -1;
        if (answer && row_bytes(streams, channel, offset, length, p, &asked, &asked_n) < 0)
            goto fail_item;
        if (ex_exact_key(&exact, answer, k, flags[i], status[i], raw, raw_n,
                         answer ? flags[p] & mode : 0, asked, asked_n) < 0)
            goto fail_item;
        keyed = 1;
        last_n = raw_n; /* the row's bytes are the exact key's from byte 9 (ex_exact_key) */
        const unsigned char *r = (const unsigned char *)raw, *q = (const unsigned char *)asked;
        ExSlot *s = NULL;
        /* the shape key first, as Describer.contents looks its up first */
        if (unit[i] && !(flags[i] & valued) && !(answer && (flags[p] & valued))) {
            int in = ex_in(bound, unit[i]);
            if (in < 0) goto fail_item;
            int got = in ? 0 : ls_free_key(&free_key, k, fc[i], flags[i], status[i], r, raw_n,
                                          answer ? q : NULL, asked_n);
            if (got < 0) goto fail_item;
            if (got) {
                keyed |= 2;
                s = ex_slot(et, ex_hash((const unsigned char *)free_key.p, free_key.n),
                            free_key.p, free_key.n);
                if (s->template == NULL) s = NULL;
            }
        }
        if (s == NULL) {
            s = ex_slot(et, ex_hash((const unsigned char *)exact.p, exact.n), exact.p, exact.n);
            if (s->template == NULL) goto slow_path;
        }
        PyObject *tp = s->template;
        int timed = PyTuple_GET_ITEM(tp, json ? 5 : 4) == Py_True;
        /* the latency, where the line shows one */
        double ms = 0.0;
        int bound_ = 0, has_ms = 0;
        if (timed && p != -1 && (json || k != K_REQUEST)) {
            if (!measured) goto slow_path;
            Py_ssize_t req = k != K_REQUEST ? p : i, resp = k != K_REQUEST ? i : p;
            if (!isfinite(t_start[resp]) || !isfinite(t_end[req])) goto slow_path;
            has_ms = ls_latency(&lp, t_start[resp], t_end[req], &ms, &bound_);
            if (has_ms < 0) goto fail_item;
        }
        if (!json) {
            /* an FC 5/6 write of another value than its content's: the row's value said
             * between the parts of the tail kept (Lister._text_line) */
            PyObject *single = PyTuple_GET_ITEM(tp, 5), *kept = PyTuple_GET_ITEM(tp, 3);
            char said[6];
            int said_n = -1; /* -1: the tail kept is the row's */
            if (single != Py_None &&
                !(PyBytes_GET_SIZE(kept) == raw_n &&
                  memcmp(PyBytes_AS_STRING(kept), raw, (size_t)raw_n) == 0)) {
                said_n = PyTuple_GET_SIZE(single) ? ls_said(said, r, raw_n) : 0;
                if (!said_n) goto slow_path;
            }
            if (ls_put_time(&out, t_start[i] - origin, 6) < 0) goto fail_item;
            int bad = 0;
            PyObject *shown = NULL;
            int owned = 0;
            if (has_ms && ls_lat_text(lt, text, ms, bound_, &shown, &owned) < 0) goto fail_item;
            int latency = shown != NULL && PyUnicode_GET_LENGTH(shown) > 0;
            if (said_n > 0) {
                bad = ls_put_str(&out, PyTuple_GET_ITEM(tp, 0)) < 0 ||
                      (latency && ls_put_str(&out, shown) < 0) ||
                      ls_put_str(&out, PyTuple_GET_ITEM(single, 0)) < 0 ||
                      buf_put(&out, said, said_n) < 0 ||
                      ls_put_str(&out, PyTuple_GET_ITEM(single, 1)) < 0;
            } else if (latency) {
                bad = ls_put_str(&out, PyTuple_GET_ITEM(tp, 0)) < 0 || ls_put_str(&out, shown) < 0 ||
                      ls_put_str(&out, PyTuple_GET_ITEM(tp, 1)) < 0;
            } else {
                bad = ls_put_str(&out, PyTuple_GET_ITEM(tp, 2)) < 0;
            }
            if (owned) Py_DECREF(shown);
            if (bad || buf_put(&out, "\n", 1) < 0) goto fail_item;
        } else {
            PyObject *kept = PyTuple_GET_ITEM(tp, 4);
            int same = PyBytes_GET_SIZE(kept) == 0 ||
                       (PyBytes_GET_SIZE(kept) == raw_n &&
                        memcmp(PyBytes_AS_STRING(kept), raw, (size_t)raw_n) == 0);
            if (!same) {
                PyObject *sp = PyTuple_GET_ITEM(tp, 3);
                if (sp == Py_None || PyBytes_GET_SIZE(kept) != raw_n) goto slow_path;
                int got = ls_splice(&first, &spliced, sp, r, raw_n);
                if (got < 0) goto fail_item;
                if (!got) goto slow_path;
            }
            int request = k == K_REQUEST;
            if (buf_put(&out, "{\"index\": ", 10) < 0 || ls_put_int(&out, base + i) < 0 ||
                buf_put(&out, ", \"t\": ", 7) < 0 || ls_put_rounded(&out, t_start[i], 6) < 0 ||
                buf_put(&out, ", \"t_end\": ", 11) < 0 || ls_put_rounded(&out, t_end[i], 6) < 0 ||
                buf_put(&out, ", ", 2) < 0 ||
                (same ? ls_put_str(&out, PyTuple_GET_ITEM(tp, 0)) : buf_put(&out, first.p, first.n)) < 0 ||
                buf_put(&out, ", \"channel\": ", 13) < 0 || ls_put_int(&out, channel[i]) < 0 ||
                buf_put(&out, ", ", 2) < 0 ||
                (same ? ls_put_str(&out, PyTuple_GET_ITEM(tp, 1)) : buf_put(&out, spliced.p, spliced.n)) < 0)
                goto fail_item;
            /* the transaction (listing.py: _transaction_json) */
            if ((k == K_REQUEST || k == K_RESPONSE || k == K_EXCEPTION || k == K_UNKNOWN) && status[i]) {
                if (status[i] >= PyTuple_GET_SIZE(statuses)) goto slow_path;
                Py_ssize_t req = request || p == -1 ? i : p;
                if (buf_put(&out, ", \"transaction\": {\"id\": ", 24) < 0 || ls_put_int(&out, base + req) < 0 ||
                    buf_put(&out, request ? ", \"role\": \"request\", \"latency_ms\": "
                                          : ", \"role\": \"response\", \"latency_ms\": ",
                            request ? 35 : 36) < 0 ||
                    ((has_ms && !bound_) ? ls_put_rounded(&out, ms, 3) : buf_put(&out, "null", 4)) < 0 ||
                    buf_put(&out, ", \"latency_max_ms\": ", 20) < 0 ||
                    ((has_ms && bound_) ? ls_put_rounded(&out, ms, 3) : buf_put(&out, "null", 4)) < 0 ||
                    buf_put(&out, ", \"status\": ", 12) < 0 ||
                    ls_put_str(&out, PyTuple_GET_ITEM(statuses, status[i])) < 0 ||
                    buf_put(&out, ", \"partner\": ", 13) < 0 ||
                    (p == -1 ? buf_put(&out, "null", 4) : ls_put_int(&out, base + p)) < 0 ||
                    buf_put(&out, "}", 1) < 0)
                    goto fail_item;
            }
            PyObject *registers = PyTuple_GET_ITEM(tp, 2);
            if (PyUnicode_GET_LENGTH(registers) &&
                (buf_put(&out, ", ", 2) < 0 || ls_put_str(&out, registers) < 0))
                goto fail_item;
            if (ls_put_str(&out, timing) < 0 || buf_put(&out, "}\n", 2) < 0) goto fail_item;
        }
        found += 1;
        Py_DECREF(item);
        continue;
    slow_path: {
        out.n = line_at; /* a line begun is taken back */
        PyObject *got = PyObject_CallOneArg(miss, item);
        Py_DECREF(item);
        if (got == NULL) goto fail;
        PyObject *line, *template;
        if (!PyTuple_CheckExact(got) || PyTuple_GET_SIZE(got) != 2 ||
            !PyUnicode_Check(line = PyTuple_GET_ITEM(got, 0))) {
            PyErr_SetString(PyExc_TypeError, "listing_rows: miss gives (str, template)");
            Py_DECREF(got);
            goto fail;
        }
        template = PyTuple_GET_ITEM(got, 1);
        if (ls_put_str(&out, line) < 0 || buf_put(&out, "\n", 1) < 0) {
            Py_DECREF(got);
            goto fail;
        }
        if (keyed && template != Py_None) {
            if (!ls_template_ok(template, json)) {
                PyErr_SetString(PyExc_TypeError, "listing_rows: not a line template");
                Py_DECREF(got);
                goto fail;
            }
            /* under the exact key only the parts of these very bytes (a content of
             * other bytes may say other values: Python splices them in, this loop
             * does only under the shape keys) */
            PyObject *made = PyTuple_GET_ITEM(template, json ? 4 : 3);
            int own = !PyBytes_GET_SIZE(made) ||
                      (PyBytes_GET_SIZE(made) == last_n &&
                       memcmp(PyBytes_AS_STRING(made), exact.p + 9, (size_t)last_n) == 0);
            if ((own && ex_keep(et, &exact, template) < 0) ||
                ((keyed & 2) && ex_keep(et, &free_key, template) < 0)) {
                Py_DECREF(got);
                goto fail;
            }
        }
        Py_DECREF(got);
        continue;
    }
    fail_item:
        Py_DECREF(item);
        goto fail;
    }
    {
        PyObject *lines = PyUnicode_DecodeUTF8(out.p, out.n, "strict");
        if (lines != NULL)
            result = Py_BuildValue("(NnnO)", lines, done, found, more ? Py_True : Py_False);
    }
    goto done_;
fail:
    Py_CLEAR(result);
done_:
    et->running = 0;
    et->out = out;
    et->exact = exact;
    et->free_key = free_key;
    et->packet_key = spliced;
    buf_free(&first);
    Py_XDECREF(streams);
    release_all(c, ROW_COLUMNS);
    return result;
}

/* ---- the sidecar's partners, numbered in another range ---------------------------------- */

/* shift_partners(partner, at_least, by) -> bytes: the int32 partner column of a block
 * with each partner p at or above `at_least` moved to p + by and every other one (none,
 * or a row out of the range) made -1 (sniffer/session/index.py: shifted_partners, the
 * reference), which is a generator over every row of the block. */
static PyObject *py_shift_partners(PyObject *self, PyObject *args) {
    Py_buffer pv;
    long long at_least, by;
    if (!PyArg_ParseTuple(args, "y*LL", &pv, &at_least, &by)) return NULL;
    PyObject *result = NULL;
    if (pv.len % 4) {
        PyErr_SetString(PyExc_ValueError, "shift_partners: not a column of int32");
        goto done;
    }
    Py_ssize_t n = pv.len / 4;
    result = PyBytes_FromStringAndSize(NULL, pv.len);
    if (result == NULL) goto done;
    const int32_t *src = (const int32_t *)pv.buf;
    int32_t *out = (int32_t *)PyBytes_AS_STRING(result);
    for (Py_ssize_t i = 0; i < n; i++) {
        long long p = src[i];
        if (p < at_least) {
            out[i] = -1;
            continue;
        }
        long long q = p + by;
        if (q < -1 || q > INT32_MAX) {
            Py_CLEAR(result);
            PyErr_SetString(PyExc_OverflowError, "shift_partners: a row past 32 bits");
            goto done;
        }
        out[i] = (int32_t)q;
    }
done:
    PyBuffer_Release(&pv);
    return result;
}

/* bounds(column, code) -> (low, high), or None for an empty column: the least and the
 * greatest of a column of words of array typecode `code` ("B", "H", "i", "I" or "Q"),
 * which the sidecar's checks take of every block (sniffer/session/index.py: _bounds, the
 * reference, is min and max over the column, a Python int a word). */
static PyObject *py_bounds(PyObject *self, PyObject *args) {
    Py_buffer v;
    int code;
    if (!PyArg_ParseTuple(args, "y*C", &v, &code)) return NULL;
    PyObject *result = NULL;
    Py_ssize_t width = code == 'B' ? 1 : code == 'H' ? 2 : code == 'i' || code == 'I' ? 4
                                                     : code == 'Q'                 ? 8
                                                                                   : 0;
    if (width == 0 || v.len % width) {
        PyErr_SetString(PyExc_ValueError, "bounds: a column of B, H, i, I or Q words");
        goto done;
    }
    Py_ssize_t n = v.len / width;
    if (n == 0) {
        result = Py_NewRef(Py_None);
        goto done;
    }
    if (code == 'i') {
        const int32_t *w = v.buf;
        int32_t lo = w[0], hi = w[0];
        for (Py_ssize_t i = 1; i < n; i++) {
            if (w[i] < lo) lo = w[i];
            if (w[i] > hi) hi = w[i];
        }
        result = Py_BuildValue("(ll)", (long)lo, (long)hi);
        goto done;
    }
    uint64_t lo = UINT64_MAX, hi = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        uint64_t x;
        if (width == 1) {
            x = ((const uint8_t *)v.buf)[i];
        } else if (width == 2) {
            x = ((const uint16_t *)v.buf)[i];
        } else if (width == 4) {
            x = ((const uint32_t *)v.buf)[i];
        } else {
            x = ((const uint64_t *)v.buf)[i];
        }
        if (x < lo) lo = x;
        if (x > hi) hi = x;
    }
    result = Py_BuildValue("(KK)", (unsigned long long)lo, (unsigned long long)hi);
done:
    PyBuffer_Release(&v);
    return result;
}

/* ---- the poll cycle's waits, counted in buckets ------------------------------------------ */

/* waits_count(seq, inv, quantum, dense, far, exact) -> (high, exact), or None
 * _Waits.count's counting (sniffer/analysis/pollcycle.py: _Waits._count, the reference):
 * each wait between consecutive float64 times of `seq` in the bucket
 * floor((b - a) * inv), `inv` being 1 / quantum as Python divides it; a bucket
 * 0 <= k < len(dense) counted in `dense` (uint32 words, in place), any other in the dict
 * `far` ({bucket: count}: the _Waits' Counter, in place). `high`: the greatest bucket;
 * `exact`: still true where `exact` was and every wait is a whole number of quanta
 * (k * quantum == b - a). None, with nothing counted: a wait that is not a number, is
 * infinite, or whose bucket passes 63 bits (Python counts those). The buckets of `far`
 * are summed here first (a host's reads give waits of few values), then added to it a
 * distinct bucket at a time. */
static PyObject *py_waits_count(PyObject *self, PyObject *args) {
    Py_buffer sv, dv;
    double inv, quantum;
    PyObject *far;
    int exact;
    if (!PyArg_ParseTuple(args, "y*ddw*O!p", &sv, &inv, &quantum, &dv, &PyDict_Type, &far,
                          &exact))
        return NULL;
    PyObject *result = NULL;
    int64_t *keys = NULL, *slot_key = NULL;
    Py_ssize_t *slot_count = NULL;
    if (sv.len % 8 || dv.len % 4 || sv.len < 16) {
        PyErr_SetString(PyExc_ValueError, "waits_count: two float64 times or more, uint32 buckets");
        goto done;
    }
    Py_ssize_t n = sv.len / 8 - 1, span = dv.len / 4;
    const double *t = sv.buf;
    uint32_t *dense = dv.buf;
    keys = PyMem_Malloc(sizeof(int64_t) * (size_t)n);
    if (keys == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    int64_t high = INT64_MIN;
    Py_ssize_t outside = 0; /* waits whose bucket is not a dense one */
    for (Py_ssize_t i = 0; i < n; i++) {
        double w = t[i + 1] - t[i];
        double y = floor(w * inv);
        if (!(y > -9.2e18 && y < 9.2e18)) { /* NaN, infinite, or past 63 bits */
            result = Py_NewRef(Py_None);
            goto done;
        }
        int64_t k = (int64_t)y;
        keys[i] = k;
        if (k > high) high = k;
        if (exact && (double)k * quantum != w) exact = 0;
        outside += !(k >= 0 && k < span);
    }
    Py_ssize_t cap = 16;
    while (cap < 2 * outside) cap *= 2;
    if (outside) {
        slot_key = PyMem_Malloc(sizeof(int64_t) * (size_t)cap);
        slot_count = PyMem_Calloc((size_t)cap, sizeof(Py_ssize_t));
        if (slot_key == NULL || slot_count == NULL) {
            PyErr_NoMemory();
            goto done;
        }
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t k = keys[i];
        if (k >= 0 && k < span) {
            dense[k] += 1;
            continue;
        }
        Py_ssize_t j = (Py_ssize_t)(((uint64_t)k * 0x9E3779B97F4A7C15ull) >> 40) & (cap - 1);
        while (slot_count[j] && slot_key[j] != k) j = (j + 1) & (cap - 1);
        slot_key[j] = k;
        slot_count[j] += 1;
    }
    for (Py_ssize_t j = 0; outside && j < cap; j++) {
        if (!slot_count[j]) continue;
        PyObject *key = PyLong_FromLongLong(slot_key[j]);
        if (key == NULL) goto done;
        PyObject *had = PyDict_GetItemWithError(far, key);
        PyObject *value = NULL;
        if (had != NULL) {
            PyObject *more = PyLong_FromSsize_t(slot_count[j]);
            value = more == NULL ? NULL : PyNumber_Add(had, more);
            Py_XDECREF(more);
        } else if (!PyErr_Occurred()) {
            value = PyLong_FromSsize_t(slot_count[j]);
        }
        int bad = value == NULL || PyDict_SetItem(far, key, value) < 0;
        Py_XDECREF(value);
        Py_DECREF(key);
        if (bad) goto done;
    }
    result = Py_BuildValue("(LO)", (long long)high, exact ? Py_True : Py_False);
done:
    PyMem_Free(keys);
    PyMem_Free(slot_key);
    PyMem_Free(slot_count);
    PyBuffer_Release(&sv);
    PyBuffer_Release(&dv);
    return result;
}

/* waits_densify(far, span, dense, kept, exact) -> (shift, exact), or None
 * _Waits.densify's steps (sniffer/analysis/pollcycle.py, whose Python is the reference):
 * the buckets of the dict `far` ({bucket: count}) sorted, the first whose running count
 * passes 99 % of them taken as the 99th percentile `p`, and `shift` the least that makes
 * span << shift reach 2 * p (at least 1); each bucket k is then counted in
 * `dense[k >> shift]` (span uint32 words, zero, in place) where that is below span and
 * in the dict `kept` (empty, in place) otherwise, in the sorted order of the keys (the
 * Counter's order, as Python fills it), a key of count 0 too. `exact`: false where it was,
 * or where a bucket is not a whole number of the wider ones. None, with `far` untouched
 * (`dense` and `kept` are then to be let go): a key or count past what 61 bits hold, or a
 * dense word past 32 bits (Python counts those). A request's waits come here once, some
 * 32k distinct keys of a request sent EXACT times at exact stamps: sorted in Python, keys
 * of a second's wait (about 2 ** 30 quanta) compared as long ints, and a Python step a key
 * after, 0.5 of the 2.9 s of 5M frames of mix738335539 under cProfile (61 requests). */
typedef struct {
    int64_t key, count;
} KeyCount;

static int keycount_cmp(const void *a, const void *b) {
    int64_t x = ((const KeyCount *)a)->key, y = ((const KeyCount *)b)->key;
    return (x > y) - (x < y);
}

static PyObject *py_waits_densify(PyObject *self, PyObject *args) {
    PyObject *far, *kept;
    Py_ssize_t span;
    Py_buffer dv;
    int exact;
    if (!PyArg_ParseTuple(args, "O!nw*O!p", &PyDict_Type, &far, &span, &dv, &PyDict_Type, &kept,
                          &exact))
        return NULL;
    PyObject *result = NULL;
    KeyCount *items = NULL;
    const int64_t LIMIT = (int64_t)1 << 61;
    if (span < 1 || span > LIMIT || dv.len != span * 4 || PyDict_GET_SIZE(kept) != 0) {
        PyErr_SetString(PyExc_ValueError, "waits_densify: span uint32 buckets, kept empty");
        goto done;
    }
    uint32_t *dense = dv.buf;
    Py_ssize_t n = PyDict_GET_SIZE(far);
    items = PyMem_Malloc(sizeof(KeyCount) * (size_t)(n ? n : 1));
    if (items == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    {
        Py_ssize_t at = 0, i = 0;
        PyObject *key, *value;
        while (PyDict_Next(far, &at, &key, &value)) {
            int over_k = 0, over_c = 0;
            long long k = PyLong_Check(key) ? PyLong_AsLongLongAndOverflow(key, &over_k) : 0;
            long long c = PyLong_Check(value) ? PyLong_AsLongLongAndOverflow(value, &over_c) : 0;
            if (PyErr_Occurred()) goto done;
            if (!PyLong_Check(key) || !PyLong_Check(value) || over_k || over_c || k > LIMIT ||
                k < -LIMIT || c < 0 || c > LIMIT) {
                result = Py_NewRef(Py_None);
                goto done;
            }
            items[i].key = k;
            items[i].count = c;
            i++;
        }
    }
    qsort(items, (size_t)n, sizeof(KeyCount), keycount_cmp);
    int64_t total = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        total += items[i].count;
        if (total > LIMIT) {
            result = Py_NewRef(Py_None);
            goto done;
        }
    }
    int64_t rank = total * 99 / 100, running = 0, high = 1;
    for (Py_ssize_t i = 0; i < n; i++) {
        running += items[i].count;
        if (running > rank) {
            high = 2 * items[i].key > 1 ? 2 * items[i].key : 1;
            break;
        }
    }
    int shift = 0; /* span << shift stays below 2 ** 63: span and high at most 2 ** 61 */
    while (((int64_t)span << shift) < high) shift++;
    int64_t low = ((int64_t)1 << shift) - 1, limit = (int64_t)span << shift;
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t k = items[i].key;
        if (k & low) exact = 0;
        if (k >= 0 && k < limit) {
            uint64_t sum = (uint64_t)dense[k >> shift] + (uint64_t)items[i].count;
            if (sum > UINT32_MAX) {
                result = Py_NewRef(Py_None);
                goto done;
            }
            dense[k >> shift] = (uint32_t)sum;
        }
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t k = items[i].key;
        if (k >= 0 && k < limit) continue;
        PyObject *wide = PyLong_FromLongLong(k >> shift); /* floors, as Python's >> */
        if (wide == NULL) goto done;
        PyObject *had = PyDict_GetItemWithError(kept, wide);
        int64_t before = 0;
        if (had != NULL) {
            before = PyLong_AsLongLong(had);
        } else if (PyErr_Occurred()) {
            Py_DECREF(wide);
            goto done;
        }
        PyObject *value = PyLong_FromLongLong(before + items[i].count);
        int bad = value == NULL || PyDict_SetItem(kept, wide, value) < 0;
        Py_XDECREF(value);
        Py_DECREF(wide);
        if (bad) goto done;
    }
    result = Py_BuildValue("(iO)", shift, exact ? Py_True : Py_False);
done:
    PyMem_Free(items);
    PyBuffer_Release(&dv);
    return result;
}

/* ---- the numbers said back ---------------------------------------------------------- */

/* One entry of constants(): `value` (a new reference, or NULL with an exception set) put
 * under `name`. 0, or -1 with an exception set. */
static int put(PyObject *d, const char *name, PyObject *value) {
    if (value == NULL) return -1;
    int r = PyDict_SetItemString(d, name, value);
    Py_DECREF(value);
    return r;
}

/* The codes 0-255 marked in `marks`, as a tuple. */
static PyObject *codes_marked(const unsigned char *marks) {
    PyObject *list = PyList_New(0), *tuple = NULL;
    if (list == NULL) return NULL;
    for (int c = 0; c < 256; c++) {
        if (!marks[c]) continue;
        PyObject *code = PyLong_FromLong(c);
        if (code == NULL || PyList_Append(list, code) < 0) {
            Py_XDECREF(code);
            Py_DECREF(list);
            return NULL;
        }
        Py_DECREF(code);
    }
    tuple = PyList_AsTuple(list);
    Py_DECREF(list);
    return tuple;
}

/* constants() -> {name: value}: every number of the product this file says itself (see
 * "the product's numbers" above, and the limits of the pcap walks and the RTU fast
 * paths), the function-code tests as the tuple of the codes each holds for. */
static PyObject *py_constants(PyObject *self, PyObject *unused) {
    static const struct {
        const char *name;
        long long value;
    } ints[] = {
        {"NOISE", K_NOISE},
        {"REQUEST", K_REQUEST},
        {"RESPONSE", K_RESPONSE},
        {"EXCEPTION", K_EXCEPTION},
        {"UNKNOWN", K_UNKNOWN},
        {"EVENT", K_EVENT},
        {"S_OK", S_OK},
        {"S_EXCEPTION", S_EXCEPTION},
        {"S_TIMEOUT", S_TIMEOUT},
        {"S_ORPHAN", S_ORPHAN},
        {"S_BROADCAST", S_BROADCAST},
        {"S_OPEN", S_OPEN},
        {"S_BAD_ANSWER", S_BAD_ANSWER},
        {"CHECK_BAD", F_CHECK_BAD},
        {"NON_HEX", F_NON_HEX},
        {"ENVELOPE_BAD", F_ENVELOPE_BAD},
        {"ASCII", F_ASCII},
        {"MBAP", F_MBAP},
        {"BAD_CHECK", BAD_CHECK_BITS},
        {"RETRY", F_RETRY},
        {"LATE", F_LATE},
        {"ANSWERED_BROADCAST", F_ANSWERED_BROADCAST},
        {"EXCEPTION_BIT", EXCEPTION_BIT},
        {"TABLE_REQUEST_LENGTH", TABLE_REQUEST_LENGTH},
        {"MULTIPLE_COUNT_AT", MULTIPLE_COUNT_AT},
        {"MULTIPLE_BASE", MULTIPLE_BASE},
        {"READ_ANSWER_BASE", READ_ANSWER_BASE},
        {"EXCEPTION_LENGTH", EXCEPTION_LENGTH},
        {"MIN_RTU", MIN_RTU},
        {"MAX_RTU", MAX_RTU},
        {"FIXED", FIXED},
        {"ECHO", ECHO},
        {"WALKED", WALKED},
        {"BLOCK_EPB", BLOCK_EPB},
        {"MAX_BLOCK", MAX_BLOCK},
        {"RTAC_HEADER_LEN", RTAC_HEADER_LEN},
        {"RTAC_DATA_RX_START", RTAC_DATA_RX_START},
        {"EPB_FLAGS", EPB_FLAGS},
        {"MAX_BATCH_BYTES", MAX_BATCH_BYTES},
    };
    static const struct {
        const char *name;
        double value;
    } floats[] = {
        {"MAX_TIME", MAX_TIME},
        {"RTAC_MAX_LEAD", RTAC_MAX_LEAD},
        {"MAX_BATCH_SPAN", MAX_BATCH_SPAN},
    };
    unsigned char marks[7][256];
    for (int c = 0; c < 256; c++) {
        marks[0][c] = FC_READ(c);
        marks[1][c] = FC_READ_BITS(c);
        marks[2][c] = FC_READ_REGISTERS(c);
        marks[3][c] = FC_WRITE_SINGLE(c);
        marks[4][c] = FC_WRITE_COIL(c);
        marks[5][c] = FC_WRITE_MULTIPLE(c);
        marks[6][c] = FC_WRITE_COILS(c);
    }
    static const char *tests[7] = {
        "FC_READ",       "FC_READ_BITS",      "FC_READ_REGISTERS", "FC_WRITE_SINGLE",
        "FC_WRITE_COIL", "FC_WRITE_MULTIPLE", "FC_WRITE_COILS",
    };
    PyObject *d = PyDict_New();
    if (d == NULL) return NULL;
    for (size_t k = 0; k < sizeof ints / sizeof ints[0]; k++)
        if (put(d, ints[k].name, PyLong_FromLongLong(ints[k].value)) < 0) goto fail;
    for (size_t k = 0; k < sizeof floats / sizeof floats[0]; k++)
        if (put(d, floats[k].name, PyFloat_FromDouble(floats[k].value)) < 0) goto fail;
    for (int k = 0; k < 7; k++)
        if (put(d, tests[k], codes_marked(marks[k])) < 0) goto fail;
    return d;
fail:
    Py_DECREF(d);
    return NULL;
}

static PyMethodDef methods[] = {
    {"crc16", py_crc16, METH_O, "CRC-16/MODBUS of a bytes-like object."},
    {"bulk_epbs", py_bulk_epbs, METH_VARARGS, "pcapng data packets (link types 250, 147) of one batch."},
    {"bulk_pcap", py_bulk_pcap, METH_VARARGS, "Classic pcap data packets of one batch."},
    {"rtu_scan", py_rtu_scan, METH_VARARGS, "The RTU framer's fast paths over reads."},
    {"pair_rows", py_pair_rows, METH_VARARGS, "FrameStore.pair_rows over int64 pairs."},
    {"pair_update", py_pair_update, METH_VARARGS, "Pairer.update's loop over new rows."},
    {"stats_scan", py_stats_scan, METH_VARARGS, "Stats.update's counts over new rows."},
    {"sunspec_rows", py_sunspec_rows, METH_VARARGS, "The rows SunSpec's tracker may take."},
    {"mask_rows", py_mask_rows, METH_VARARGS, "The rows a mask of bytes marks, as int64."},
    {"join_reads", py_join_reads, METH_O, "Consecutive batches of reads as one."},
    {"ranked", py_ranked, METH_VARARGS, "Values at ranks of the sorted values, by selection."},
    {"poll_table", py_poll_table, METH_O, "A table of the distinct keys of PollCycles.add."},
    {"poll_block", py_poll_block, METH_VARARGS, "PollCycles.add's requests of a block, grouped."},
    {"tally_latencies", py_tally_latencies, METH_VARARGS, "Tallies.add_latencies' counting."},
    {"tally_gaps", py_tally_gaps, METH_VARARGS, "Tallies.add_requests' counting."},
    {"export_table", py_export_table, METH_NOARGS, "A table of the export's packet templates."},
    {"export_rows", py_export_rows, METH_VARARGS, "PcapExporter.write's blocks of a run of rows."},
    {"export_moved", py_export_moved, METH_VARARGS, "exported_timing's largest move."},
    {"listing_table", py_listing_table, METH_NOARGS, "A table of the listings' line templates."},
    {"listing_floats", py_listing_floats, METH_VARARGS, "listing_rows' round, repr and time of a float."},
    {"listing_rows", py_listing_rows, METH_VARARGS, "Lister.write's text or JSONL lines of a run of rows."},
    {"shift_partners", py_shift_partners, METH_VARARGS, "A block's partners in another range."},
    {"bounds", py_bounds, METH_VARARGS, "The least and greatest word of a column."},
    {"waits_count", py_waits_count, METH_VARARGS, "_Waits.count's counting in buckets."},
    {"waits_densify", py_waits_densify, METH_VARARGS, "_Waits.densify's buckets."},
    {"constants", py_constants, METH_NOARGS, "The product's numbers this module says itself."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "sniffer._core", "modscope's compiled core (optional).", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__core(void) {
    crc_init();
    PyObject *m = PyModule_Create(&module);
    if (m == NULL) return NULL;
    return m;
}

/* ---- the poll cycle's requests and the bounded statistics' tallies -------------------- */

/* poll_table(rules) -> a table of the distinct request keys met by one PollCycles.add
 * (sniffer/analysis/pollcycle.py): a key is a row's bytes, with its framing (flags & the
 * `apart` bits: ASCII, Modbus TCP) where it has any, or a write's identity (see
 * write_identity), and each maps to the group Python gave it (one group per _Sent). The
 * bytes are kept in an arena, the slots point into it.
 * `rules` is the same-poll rule of the writes (sniffer/analysis/polls.py: core_rules), a
 * tuple of (code, multiple, low, high, bits, values) for each code whose writes are keyed
 * by their identity: a multiple write (address, quantity, byte count, values) whose
 * quantity is from low to high and whose byte count is what the quantity needs (a byte
 * for 8 values of a table of bits, else 2 a value), or a single write (address, value) of
 * one of `values` (None: any value). */
#define RULE_VALUES 8 /* the most values a single write's rule may list */

typedef struct {
    uint64_t hash;
    Py_ssize_t at, size, group; /* group -1: an empty slot */
    uint32_t framing;
} PollKey;

typedef struct {
    unsigned char form; /* 0: writes of this code keep their bytes as their key */
    unsigned char bits;
    unsigned char n_values; /* 0: any value */
    unsigned int low, high;
    unsigned int values[RULE_VALUES];
} PollRule;

#define RULE_SINGLE 1
#define RULE_MULTIPLE 2

typedef struct {
    PollKey *slots;
    Py_ssize_t cap, used;
    Buf arena;
    PollRule rules[256];
} PollTable;

static void poll_table_free(PyObject *capsule) {
    PollTable *pt = PyCapsule_GetPointer(capsule, "modscope.poll_table");
    if (pt == NULL) return;
    PyMem_Free(pt->slots);
    buf_free(&pt->arena);
    PyMem_Free(pt);
}

/* One rule of poll_table's `rules` into `rules`. 0, or -1 with an exception set. */
static int poll_rule(PyObject *item, PollRule *rules) {
    int code, multiple, bits;
    unsigned int low, high;
    PyObject *values;
    if (!PyTuple_Check(item) ||
        !PyArg_ParseTuple(item, "ipIIpO", &code, &multiple, &low, &high, &bits, &values)) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_TypeError,
                            "poll_table: a rule is (code, multiple, low, high, bits, values)");
        return -1;
    }
    if (code < 0 || code > 255 || rules[code].form) {
        PyErr_Format(PyExc_ValueError, "poll_table: code %d out of range or given twice", code);
        return -1;
    }
    if (low > high || high > 0xFFFF) {
        PyErr_SetString(PyExc_ValueError, "poll_table: quantities are 0 <= low <= high <= 65535");
        return -1;
    }
    PollRule *r = &rules[code];
    if (values != Py_None) {
        if (!PyTuple_Check(values) || PyTuple_GET_SIZE(values) < 1 ||
            PyTuple_GET_SIZE(values) > RULE_VALUES) {
            PyErr_Format(PyExc_ValueError, "poll_table: values are None or 1 to %d ints",
                         RULE_VALUES);
            return -1;
        }
        for (Py_ssize_t k = 0; k < PyTuple_GET_SIZE(values); k++) {
            long v = PyLong_AsLong(PyTuple_GET_ITEM(values, k));
            if (v == -1 && PyErr_Occurred()) return -1;
            if (v < 0 || v > 0xFFFF) {
                PyErr_SetString(PyExc_ValueError, "poll_table: a value is 16 bits");
                return -1;
            }
            r->values[k] = (unsigned int)v;
        }
        r->n_values = (unsigned char)PyTuple_GET_SIZE(values);
    }
    r->form = multiple ? RULE_MULTIPLE : RULE_SINGLE;
    r->bits = (unsigned char)bits;
    r->low = low;
    r->high = high;
    return 0;
}

static PyObject *py_poll_table(PyObject *self, PyObject *rules) {
    PyObject *seq = PySequence_Fast(rules, "poll_table: the rules are a sequence");
    if (seq == NULL) return NULL;
    PollTable *pt = PyMem_Calloc(1, sizeof(PollTable));
    if (pt == NULL) {
        Py_DECREF(seq);
        return PyErr_NoMemory();
    }
    for (Py_ssize_t k = 0; k < PySequence_Fast_GET_SIZE(seq); k++) {
        if (poll_rule(PySequence_Fast_GET_ITEM(seq, k), pt->rules) < 0) {
            Py_DECREF(seq);
            PyMem_Free(pt);
            return NULL;
        }
    }
    Py_DECREF(seq);
    PyObject *capsule = PyCapsule_New(pt, "modscope.poll_table", poll_table_free);
    if (capsule == NULL) PyMem_Free(pt);
    return capsule;
}

static uint64_t poll_hash(const unsigned char *p, Py_ssize_t n, uint32_t framing) {
    uint64_t h = 1469598103934665603ull ^ framing; /* FNV-1a */
    for (Py_ssize_t k = 0; k < n; k++) h = (h ^ p[k]) * 1099511628211ull;
    return h ^ (h >> 29);
}

/* The slot of a key: its own, or the empty one where it goes. */
static PollKey *poll_slot(PollTable *pt, uint64_t h, const char *p, Py_ssize_t n,
                          uint32_t framing) {
    Py_ssize_t mask = pt->cap - 1, k = (Py_ssize_t)(h & (uint64_t)mask);
    for (;;) {
        PollKey *s = &pt->slots[k];
        if (s->group < 0) return s;
        if (s->hash == h && s->size == n && s->framing == framing &&
            memcmp(pt->arena.p + s->at, p, (size_t)n) == 0)
            return s;
        k = (k + 1) & mask;
    }
}

/* Room for one more key (at most half the slots used). 0, or -1 with MemoryError. */
static int poll_grow(PollTable *pt) {
    if (2 * (pt->used + 1) <= pt->cap) return 0;
    Py_ssize_t cap = pt->cap ? 2 * pt->cap : 1024;
    PollKey *slots = PyMem_Malloc(sizeof(PollKey) * (size_t)cap), *old = pt->slots;
    if (slots == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    for (Py_ssize_t k = 0; k < cap; k++) slots[k].group = -1;
    Py_ssize_t old_cap = pt->cap;
    pt->slots = slots;
    pt->cap = cap;
    for (Py_ssize_t k = 0; k < old_cap; k++) {
        if (old[k].group < 0) continue;
        Py_ssize_t j = (Py_ssize_t)(old[k].hash & (uint64_t)(cap - 1));
        while (slots[j].group >= 0) j = (j + 1) & (cap - 1);
        slots[j] = old[k];
    }
    PyMem_Free(old);
    return 0;
}

typedef struct {
    Buf times;
    Py_ssize_t retries;
    int touched;
} PollGroup;

/* The framing of a key that is a write's identity (no flag of a row has this bit). */
#define WRITE_KEY 0x80000000u

/* Whether the RTU frame p[0..n) (unit, body, CRC) is a write the table's rules read
 * (sniffer/analysis/polls.py: plain_identity reads it so too): a single write of a value
 * its rule allows, or a multiple write whose quantity is in its rule's range and whose
 * byte count is the bytes that follow and what the quantity needs. Then `same` gets what
 * its identity holds (unit, code, address, quantity), so that writes of other values
 * share one key and Python hears of the first only: a master that writes changing values
 * would otherwise make a new key, and a call into Python, of each.
 * tests/core/test_core_pollcycle.py holds the groups to the Python walk's. */
static int write_identity(const PollRule *rules, const char *p, Py_ssize_t n, char *same) {
    const unsigned char *b = (const unsigned char *)p;
    Py_ssize_t size = n - 2; /* the body: the CRC left off */
    if (size < 6) return 0;
    const PollRule *r = &rules[b[1]];
    unsigned int count;
    if (r->form == RULE_SINGLE) {
        if (size != 6) return 0;
        if (r->n_values) {
            unsigned int value = (unsigned int)b[4] << 8 | b[5];
            int found = 0;
            for (int k = 0; k < r->n_values; k++) found |= r->values[k] == value;
            if (!found) return 0;
        }
        count = 1;
    } else if (r->form == RULE_MULTIPLE) {
        if (size < 7 || size != 7 + b[6]) return 0;
        count = (unsigned int)b[4] << 8 | b[5];
        unsigned int need = r->bits ? (count + 7) / 8 : 2 * count;
        if (count < r->low || count > r->high || b[6] != need) return 0;
    } else {
        return 0;
    }
    same[0] = (char)b[0];
    same[1] = (char)b[1];
    same[2] = (char)b[2];
    same[3] = (char)b[3];
    same[4] = (char)(count >> 8);
    same[5] = (char)(count & 0xFF);
    return 1;
}

/* poll_block(table, store, lo, hi, resolve, request, bad, retry, apart)
 *     -> [(group, times, retries), ...]
 * PollCycles.add over rows lo..hi (sniffer/analysis/pollcycle.py: the requests of a block, their
 * keys as _keys makes them, grouped): the rows of kind `request` with none of the `bad`
 * flags, each keyed by its bytes (as FrameStore slices them; the one stream for every row
 * when the store has one, as _keys reads it) and, where it has any of the `apart` flags,
 * those flags: the key is then the tuple (flags & apart, bytes). A key not in `table`
 * yet is handed to `resolve(key, row)`, which says its group (an int >= 0: the _Sent it
 * is counted in); the times (float64 bytes, in the order of their rows) and the retries
 * (rows with a `retry` flag) of each group met in the block come back, in the order the
 * groups were first met. */
static PyObject *py_poll_block(PyObject *self, PyObject *args) {
    PyObject *capsule, *store, *resolve;
    Py_ssize_t lo, hi;
    int request;
    unsigned int bad, retry, apart;
    if (!PyArg_ParseTuple(args, "OOnnOiIII", &capsule, &store, &lo, &hi, &resolve, &request,
                          &bad, &retry, &apart))
        return NULL;
    PollTable *pt = PyCapsule_GetPointer(capsule, "modscope.poll_table");
    if (pt == NULL) return NULL;
    static const ColSpec specs[] = {
        {"kind", 'B', 0},   {"flags", 'I', 0},  {"t", 'd', 0},
        {"offset", 'Q', 0}, {"length", 'H', 0}, {"channel", 'B', 0},
    };
    Py_buffer c[6];
    if (columns(store, specs, 6, c) < 0) return NULL;
    PyObject *result = NULL, *streams = NULL, *single = NULL;
    PollGroup *acc = NULL;
    Py_ssize_t n_acc = 0;
    Buf met = {0}; /* the groups met, in order */
    const unsigned char *kind = c[0].buf, *channel = c[5].buf;
    const uint32_t *flags = c[1].buf;
    const double *t = c[2].buf;
    const uint64_t *offset = c[3].buf;
    const uint16_t *length = c[4].buf;
    Py_ssize_t rows = c[0].len;
    if (c[1].len != 4 * rows || c[2].len != 8 * rows || c[3].len != 8 * rows ||
        c[4].len != 2 * rows || c[5].len != rows) {
        PyErr_SetString(PyExc_ValueError, "poll_block: columns of different lengths (sync)");
        goto done;
    }
    if (lo < 0 || hi > rows || lo > hi) {
        PyErr_SetString(PyExc_ValueError, "poll_block: rows out of range");
        goto done;
    }
    streams = PyObject_GetAttrString(store, "streams");
    if (streams == NULL) goto done;
    if (!PyDict_Check(streams)) {
        PyErr_SetString(PyExc_TypeError, "poll_block: a store's streams are a dict");
        goto done;
    }
    if (PyDict_Size(streams) == 1) {
        Py_ssize_t pos = 0;
        PyObject *k, *v;
        PyDict_Next(streams, &pos, &k, &v);
        if (!PyByteArray_Check(v)) {
            PyErr_SetString(PyExc_TypeError, "a store's streams are bytearrays");
            goto done;
        }
        single = v;
        Py_INCREF(single);
    }
    for (Py_ssize_t i = lo; i < hi; i++) {
        if (kind[i] != request || (flags[i] & bad)) continue;
        const char *p;
        Py_ssize_t n;
        if (single != NULL) {
            Py_ssize_t size = PyByteArray_GET_SIZE(single);
            uint64_t start = offset[i], stop = start + length[i];
            if (start > (uint64_t)size) start = (uint64_t)size;
            if (stop > (uint64_t)size) stop = (uint64_t)size;
            p = PyByteArray_AS_STRING(single) + start;
            n = (Py_ssize_t)(stop - start);
        } else if (row_bytes(streams, channel, offset, length, i, &p, &n) < 0) {
            goto done;
        }
        uint32_t framing = flags[i] & apart;
        /* a well-formed write is keyed by what it writes to, not by its values (see
         * write_identity); the row's own bytes still go to `resolve` on a miss */
        const char *row_p = p;
        Py_ssize_t row_n = n;
        char same[6];
        if (!framing && !(apart & WRITE_KEY) && write_identity(pt->rules, p, n, same)) {
            p = same;
            n = 6;
            framing = WRITE_KEY;
        }
        uint64_t h = poll_hash((const unsigned char *)p, n, framing);
        Py_ssize_t group;
        PollKey *slot = pt->cap ? poll_slot(pt, h, p, n, framing) : NULL;
        if (slot != NULL && slot->group >= 0) {
            group = slot->group;
        } else {
            /* a new key: its group from Python (which may run any code: the key's bytes
             * are copied first, and looked up again after) */
            PyObject *raw = PyBytes_FromStringAndSize(row_p, row_n), *key = raw;
            if (raw == NULL) goto done;
            if (framing & apart) {
                key = Py_BuildValue("(IO)", framing, raw);
                Py_DECREF(raw);
                if (key == NULL) goto done;
                raw = PyTuple_GET_ITEM(key, 1);
            }
            PyObject *got = PyObject_CallFunction(resolve, "On", key, i);
            if (got == NULL) {
                Py_DECREF(key);
                goto done;
            }
            group = PyLong_AsSsize_t(got);
            Py_DECREF(got);
            if (group < 0) {
                if (!PyErr_Occurred())
                    PyErr_SetString(PyExc_ValueError, "poll_block: a group is an int >= 0");
                Py_DECREF(key);
                goto done;
            }
            const char *kp = framing == WRITE_KEY ? same : PyBytes_AS_STRING(raw);
            if (poll_grow(pt) < 0) {
                Py_DECREF(key);
                goto done;
            }
            slot = poll_slot(pt, h, kp, n, framing);
            if (slot->group < 0) {
                slot->hash = h;
                slot->at = pt->arena.n;
                slot->size = n;
                slot->framing = framing;
                if (buf_put(&pt->arena, kp, n) < 0) {
                    Py_DECREF(key);
                    goto done;
                }
                pt->used += 1;
            }
            slot->group = group;
            Py_DECREF(key);
        }
        if (group >= n_acc) {
            Py_ssize_t more = n_acc ? n_acc : 64;
            while (more <= group) more *= 2;
            PollGroup *grown = PyMem_Realloc(acc, sizeof(PollGroup) * (size_t)more);
            if (grown == NULL) {
                PyErr_NoMemory();
                goto done;
            }
            memset(grown + n_acc, 0, sizeof(PollGroup) * (size_t)(more - n_acc));
            acc = grown;
            n_acc = more;
        }
        PollGroup *g = &acc[group];
        if (!g->touched) {
            g->touched = 1;
            if (buf_put(&met, &group, sizeof group) < 0) goto done;
        }
        if (buf_put(&g->times, &t[i], 8) < 0) goto done;
        if (flags[i] & retry) g->retries += 1;
    }
    {
        Py_ssize_t count = met.n / (Py_ssize_t)sizeof(Py_ssize_t);
        const Py_ssize_t *order = (const Py_ssize_t *)met.p;
        PyObject *list = PyList_New(count);
        if (list == NULL) goto done;
        for (Py_ssize_t j = 0; j < count; j++) {
            PollGroup *g = &acc[order[j]];
            PyObject *times = buf_bytes(&g->times), *item = NULL;
            if (times != NULL) item = Py_BuildValue("(nOn)", order[j], times, g->retries);
            Py_XDECREF(times);
            if (item == NULL) {
                Py_DECREF(list);
                goto done;
            }
            PyList_SET_ITEM(list, j, item);
        }
        result = list;
    }
done:
    for (Py_ssize_t j = 0; j < n_acc; j++) buf_free(&acc[j].times);
    PyMem_Free(acc);
    buf_free(&met);
    Py_XDECREF(single);
    Py_XDECREF(streams);
    release_all(c, 6);
    return result;
}

/* The tallies of sniffer/analysis/stats.py: Tallies (a Counter: printed figure -> how many).
 * The figures of one call are counted here first, each distinct one (by ==, so 0.0 and
 * -0.0 are one, the first met kept as the Counter would keep it) once, in the order they
 * were first met, then added to the Counter as `counter[key] += count`. */
typedef struct {
    double key;
    Py_ssize_t count;
} Figure;

typedef struct {
    Figure *figures; /* in the order first met */
    Py_ssize_t n, cap;
    Py_ssize_t *index; /* hash -> figure + 1, 0 empty */
    Py_ssize_t index_cap;
    Py_ssize_t last; /* the figure counted last, + 1 (0: none) */
} Figures;

static void figures_free(Figures *f) {
    PyMem_Free(f->figures);
    PyMem_Free(f->index);
    memset(f, 0, sizeof *f);
}

static Py_ssize_t figure_slot(const Figures *f, double x) {
    double z = x == 0.0 ? 0.0 : x; /* -0.0 hashes as 0.0 */
    uint64_t bits;
    memcpy(&bits, &z, 8);
    bits ^= bits >> 31;
    bits *= 0x9E3779B97F4A7C15ull;
    Py_ssize_t mask = f->index_cap - 1, k = (Py_ssize_t)((bits >> 20) & (uint64_t)mask);
    while (f->index[k] && f->figures[f->index[k] - 1].key != x) k = (k + 1) & mask;
    return k;
}

/* Count one figure (never NaN). 0, or -1 with MemoryError. */
static int figures_count(Figures *f, double x) {
    if (f->last && f->figures[f->last - 1].key == x) { /* the same as the last: common */
        f->figures[f->last - 1].count += 1;
        return 0;
    }
    if (2 * (f->n + 1) > f->index_cap) {
        Py_ssize_t cap = f->index_cap ? 2 * f->index_cap : 256;
        Py_ssize_t *index = PyMem_Calloc((size_t)cap, sizeof(Py_ssize_t));
        if (index == NULL) {
            PyErr_NoMemory();
            return -1;
        }
        PyMem_Free(f->index);
        f->index = index;
        f->index_cap = cap;
        for (Py_ssize_t j = 0; j < f->n; j++) f->index[figure_slot(f, f->figures[j].key)] = j + 1;
    }
    Py_ssize_t k = figure_slot(f, x);
    if (f->index[k]) {
        f->last = f->index[k];
        f->figures[f->last - 1].count += 1;
        return 0;
    }
    if (f->n == f->cap) {
        Py_ssize_t cap = f->cap ? 2 * f->cap : 64;
        Figure *grown = PyMem_Realloc(f->figures, sizeof(Figure) * (size_t)cap);
        if (grown == NULL) {
            PyErr_NoMemory();
            return -1;
        }
        f->figures = grown;
        f->cap = cap;
    }
    f->figures[f->n].key = x;
    f->figures[f->n].count = 1;
    f->n += 1;
    f->index[k] = f->last = f->n;
    return 0;
}

/* counter[key] += count, as a Counter does it (a missing key counts from 0). */
static int counter_add(PyObject *counter, PyObject *key, Py_ssize_t count) {
    PyObject *old = PyDict_GetItemWithError(counter, key); /* borrowed */
    if (old == NULL && PyErr_Occurred()) return -1;
    PyObject *add = PyLong_FromSsize_t(count);
    if (add == NULL) return -1;
    PyObject *sum = old == NULL ? add : PyNumber_Add(old, add);
    if (old != NULL) Py_DECREF(add);
    if (sum == NULL) return -1;
    int r = PyDict_SetItem(counter, key, sum);
    Py_DECREF(sum);
    return r;
}

/* The figures counted so far into the Counter (ints with `whole`, floats otherwise),
 * and forgotten. 0, or -1 with an exception set. */
static int figures_flush(Figures *f, PyObject *counter, int whole) {
    for (Py_ssize_t j = 0; j < f->n; j++) {
        PyObject *key = whole ? PyLong_FromDouble(f->figures[j].key)
                              : PyFloat_FromDouble(f->figures[j].key);
        if (key == NULL) return -1;
        int r = counter_add(counter, key, f->figures[j].count);
        Py_DECREF(key);
        if (r < 0) return -1;
    }
    f->n = f->last = 0;
    if (f->index) memset(f->index, 0, sizeof(Py_ssize_t) * (size_t)f->index_cap);
    return 0;
}

/* A figure C does not round (see below): the ones so far into the Counter, then this one
 * rounded by Python itself (round(x) or round(x, 1)), raising what it raises. */
static int figure_by_python(Figures *f, PyObject *counter, int whole, double x) {
    if (figures_flush(f, counter, whole) < 0) return -1;
    PyObject *value = PyFloat_FromDouble(x);
    if (value == NULL) return -1;
    PyObject *rounded = whole ? PyObject_CallMethod(value, "__round__", NULL)
                              : PyObject_CallMethod(value, "__round__", "i", 1);
    Py_DECREF(value);
    if (rounded == NULL) return -1;
    int r = counter_add(counter, rounded, 1);
    Py_DECREF(rounded);
    return r;
}

/* counter[round(x, 3)] += 1, by Python: a latency under 0.1 ms is tallied to the
 * microsecond (Tallies.add_latencies), rare enough (a network capture's local server)
 * to be left to Python. */
static int thousandth_by_python(Figures *f, PyObject *counter, double x) {
    if (figures_flush(f, counter, 0) < 0) return -1;
    PyObject *value = PyFloat_FromDouble(x);
    if (value == NULL) return -1;
    PyObject *rounded = PyObject_CallMethod(value, "__round__", "i", 3);
    Py_DECREF(value);
    if (rounded == NULL) return -1;
    int r = counter_add(counter, rounded, 1);
    Py_DECREF(rounded);
    return r;
}

/* round(y, 1) as Python rounds a float: y's exact binary value to the nearest tenth,
 * half to even (CPython's double_round: a correctly rounded decimal string, read back),
 * which is the nearest double to q / 10 for the integer q nearest 10 * y. Here y = m *
 * 2^-s exactly (m < 2^53), so 10 * y = 10m * 2^-s: q and the remainder in integers,
 * and q / 10.0 one correctly rounded division. 0 and the figure, or -1 where this does
 * not apply (not finite, |y| >= 2^49): Python rounds those. */
static int round_tenth(double y, double *out) {
    if (!isfinite(y)) return -1;
    int e;
    double f = frexp(fabs(y), &e); /* |y| = f * 2^e, 0.5 <= f < 1 (or y == 0) */
    int s = 53 - e;
    if (s < 4) return -1; /* |y| >= 2^49: q might not be exact as a double */
    uint64_t m = (uint64_t)ldexp(f, 53), q;
    if (s > 60) {
        q = 0; /* 10m < 2^57 <= 2^(s-4): under a sixteenth */
    } else {
        uint64_t v = 10 * m, half = (uint64_t)1 << (s - 1), rem = v & ((half << 1) - 1);
        q = v >> s;
        if (rem > half || (rem == half && (q & 1))) q += 1;
    }
    double r = (double)q / 10.0;
    *out = signbit(y) ? -r : r;
    return 0;
}

/* tally_latencies(counter, values) -> how many were counted
 * Tallies.add_latencies' counting: for each latency x (float64, seconds) that is not
 * NaN, counter[latency_figure(x * 1000)] += 1: round(ms, 1), or round(ms, 3) under
 * 0.1 ms. */
static PyObject *py_tally_latencies(PyObject *self, PyObject *args) {
    PyObject *counter;
    Py_buffer vv;
    if (!PyArg_ParseTuple(args, "O!y*", &PyDict_Type, &counter, &vv)) return NULL;
    PyObject *result = NULL;
    Figures f = {0};
    const double *x = vv.buf;
    Py_ssize_t n = vv.len / 8, kept = 0;
    if (vv.len % 8) {
        PyErr_SetString(PyExc_TypeError, "tally_latencies: float64 values");
        goto done;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        if (isnan(x[i])) continue;
        kept += 1;
        double y = x[i] * 1000.0, r;
        if (fabs(y) < 0.1) {
            if (thousandth_by_python(&f, counter, y) < 0) goto done;
        } else if (round_tenth(y, &r) == 0) {
            if (figures_count(&f, r) < 0) goto done;
        } else if (figure_by_python(&f, counter, 0, y) < 0) {
            goto done;
        }
    }
    if (figures_flush(&f, counter, 0) < 0) goto done;
    result = PyLong_FromSsize_t(kept);
done:
    figures_free(&f);
    PyBuffer_Release(&vv);
    return result;
}

/* tally_gaps(counter, times, start, last) -> the last time
 * Tallies.add_requests' counting: for each request time t (float64, seconds) from
 * `start` on, counter[round((t - last) * 1000)] += 1, then last = t. Python's round of
 * a float is its nearest integer, half to even: nearbyint's (the default rounding
 * mode), then the int of that double. NaN and infinities go to Python, which raises. */
static PyObject *py_tally_gaps(PyObject *self, PyObject *args) {
    PyObject *counter;
    Py_buffer vv;
    Py_ssize_t start;
    double last;
    if (!PyArg_ParseTuple(args, "O!y*nd", &PyDict_Type, &counter, &vv, &start, &last))
        return NULL;
    PyObject *result = NULL;
    Figures f = {0};
    const double *t = vv.buf;
    Py_ssize_t n = vv.len / 8;
    if (vv.len % 8 || start < 0) {
        PyErr_SetString(PyExc_TypeError, "tally_gaps: float64 values, a start >= 0");
        goto done;
    }
    for (Py_ssize_t i = start; i < n; i++) {
        double gap = (t[i] - last) * 1000.0;
        if (isfinite(gap)) {
            if (figures_count(&f, nearbyint(gap)) < 0) goto done;
        } else if (figure_by_python(&f, counter, 1, gap) < 0) {
            goto done;
        }
        last = t[i];
    }
    if (figures_flush(&f, counter, 1) < 0) goto done;
    result = PyFloat_FromDouble(last);
done:
    figures_free(&f);
    PyBuffer_Release(&vv);
    return result;
}
