/* modscope's optional compiled core: the two loops that run once a byte or a packet.
 *
 *  - bulk_epbs: walks the blocks of a piece of a pcapng file while they are data packets
 *    (link type 250 data records, link type 147 packets) of one batch
 *    (sniffer/sources/pcap.py: _bulk_blocks);
 *  - bulk_pcap: the same over the records of a classic pcap file (_bulk_pcap_records);
 *  - rtu_scan: the RTU framer's fast paths 1 and 2 with the read-by-read timeline step
 *    (sniffer/framing.py: RtuFramer._scan_bytes, _Timeline.add_read).
 *
 * Both are copies of the Python code named, which stays the reference and the fallback:
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

static int buf_put(Buf *b, const void *src, Py_ssize_t n) {
    if (b->n + n > b->cap) {
        Py_ssize_t cap = b->cap ? b->cap : 256;
        while (cap < b->n + n) cap *= 2;
        char *p = PyMem_Realloc(b->p, (size_t)cap);
        if (p == NULL) {
            PyErr_NoMemory();
            return -1;
        }
        b->p = p;
        b->cap = cap;
    }
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

static void crc_init(void) {
    for (int i = 0; i < 256; i++) {
        uint16_t c = (uint16_t)i;
        for (int j = 0; j < 8; j++) c = (c & 1) ? (uint16_t)((c >> 1) ^ 0xA001) : (uint16_t)(c >> 1);
        crc_table[i] = c;
    }
}

static uint16_t crc16(const unsigned char *p, Py_ssize_t n) {
    uint16_t crc = 0xFFFF;
    for (Py_ssize_t i = 0; i < n; i++) crc = (uint16_t)((crc >> 8) ^ crc_table[(crc ^ p[i]) & 0xFF]);
    return crc;
}

static PyObject *py_crc16(PyObject *self, PyObject *arg) {
    Py_buffer v;
    if (PyObject_GetBuffer(arg, &v, PyBUF_SIMPLE) < 0) return NULL;
    uint16_t c = crc16((const unsigned char *)v.buf, v.len);
    PyBuffer_Release(&v);
    return PyLong_FromLong(c);
}

/* ---- pcapng: runs of data packets (link type 250 data records, link type 147) ---------- */

#define BLOCK_EPB 6u
#define MAX_BLOCK (1u << 26)
#define RTAC_HEADER_LEN 12
#define RTAC_DATA_RX_START 2
#define EPB_FLAGS 2
#define MAX_TIME 1e10
#define RTAC_MAX_LEAD 60.0
#define MAX_BATCH_SPAN 0.25
#define MAX_BATCH_BYTES (1 << 16)

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
    int bits = 0;
    for (uint64_t v = q; v; v >>= 1) bits++;
    int s = 53 - bits;
    uint64_t m = q;
    for (int i = 0; i < s; i++) {
        r <<= 1; /* r < tps <= 2**62 */
        m <<= 1;
        if (r >= tps) {
            r -= tps;
            m |= 1;
        }
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

static Py_ssize_t floordiv(Py_ssize_t a, Py_ssize_t b) {
    Py_ssize_t q = a / b;
    if ((a % b != 0) && ((a < 0) != (b < 0))) q -= 1;
    return q;
}

/* rtu_scan(buf, tables, pos, end, final, batch, pu, pf, pl, pdl, pr, row, timeout,
 *          cur_start, cur_t0, cur_rate, offset, last_end, slack, char_time, t35,
 *          too_fast, first_too_fast, ends, t_starts, t_ends, k, prev, base)
 * See RtuFramer._fast_scan, which calls it and applies what it returns. NaN stands for
 * None in last_end, first_too_fast and t_starts. */
static PyObject *py_rtu_scan(PyObject *self, PyObject *args) {
    Py_buffer view, tview, eview, sview, teview;
    Py_ssize_t pos, end, pu, pf, pl, pr, row, cur_start, offset, too_fast, k, prev, base;
    int final, batch;
    double pdl, timeout, cur_t0, cur_rate, last_end, slack, char_time, t35, first_too_fast;
    if (!PyArg_ParseTuple(args, "y*y*nnppnnndnndnddnddddndy*y*y*nnn", &view, &tview, &pos, &end,
                          &final, &batch, &pu, &pf, &pl, &pdl, &pr, &row, &timeout, &cur_start,
                          &cur_t0, &cur_rate, &offset, &last_end, &slack, &char_time, &t35,
                          &too_fast, &first_too_fast, &eview, &sview, &teview, &k, &prev, &base))
        return NULL;
    const unsigned char *buf = (const unsigned char *)view.buf;
    const int64_t *tab = (const int64_t *)tview.buf;
    const int64_t *request_base = tab, *request_count = tab + 256, *answer_pos = tab + 512,
                  *answer_base = tab + 768, *answer_item = tab + 1024, *answer_up = tab + 1280,
                  *answer_byte = tab + 1536;
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

    if (tview.len != 7 * 256 * 8) {
        PyErr_SetString(PyExc_ValueError, "tables must be 7 x 256 int64");
        goto done;
    }
    if (batch && count > k) {
        spans = PyMem_Malloc(sizeof(Span) * (size_t)(count - k));
        if (spans == NULL) {
            PyErr_NoMemory();
            goto done;
        }
    }
    Py_ssize_t pfx = pf | 0x80;
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
            if (unit == pu && fc == pf && pdl != INF) {
                if (pos < cur_start) { /* needs the timeline of older reads */
                    slow = 1;
                    goto stopped;
                }
                double t0 = cur_t0 + (double)(pos - cur_start) * cur_rate;
                if (t0 > pdl) pu = -1;
            }
            Py_ssize_t length, stop;
            if (unit == pu && (fc == pf || fc == pfx)) { /* fast path 1 */
                length = fc == pf ? pl : EXCEPTION_LENGTH;
                stop = pos + length;
                if (stop > end) {
                    if (!final) break;
                } else if (pos >= cur_start &&
                           (fc != pf || answer_pos[pf] < 0 || buf[pos + 2] == pl - 5) &&
                           crc16(buf + pos, length) == 0) {
                    double t0 = cur_t0 + (double)(pos - cur_start) * cur_rate;
                    double t1 = t0 + (double)length * cur_rate;
                    uint64_t o = (uint64_t)pos;
                    uint16_t l = (uint16_t)length;
                    unsigned char kind = fc == pf ? 2 : 3, u = (unsigned char)unit,
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
            } else { /* fast path 2 */
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
                    } else if (pos >= cur_start && crc16(buf + pos, length) == 0) {
                        Py_ssize_t ap = answer_pos[fc];
                        if (unit && ap == WALKED) { /* the answer's length needs Python */
                            slow = 1;
                            goto stopped;
                        }
                        double t0 = cur_t0 + (double)(pos - cur_start) * cur_rate;
                        double t1 = t0 + (double)length * cur_rate;
                        uint64_t o = (uint64_t)pos;
                        uint16_t l = (uint16_t)length;
                        unsigned char kind = 1, u = (unsigned char)unit, f = (unsigned char)fc;
                        if (buf_put(&c_off, &o, 8) < 0 || buf_put(&c_len, &l, 2) < 0 ||
                            buf_put(&c_t, &t0, 8) < 0 || buf_put(&c_te, &t1, 8) < 0 ||
                            buf_put(&c_kind, &kind, 1) < 0 || buf_put(&c_unit, &u, 1) < 0 ||
                            buf_put(&c_fc, &f, 1) < 0)
                            goto done;
                        pr = pu = -1;
                        pdl = INF;
                        if (unit) { /* a broadcast gets no answer */
                            pr = row;
                            if (ap >= 0) {
                                Py_ssize_t q = buf[pos + ap] << 8 | buf[pos + ap + 1];
                                pl = (Py_ssize_t)answer_base[fc] +
                                     floordiv(q * (Py_ssize_t)answer_item[fc] +
                                                  (Py_ssize_t)answer_up[fc],
                                              (Py_ssize_t)answer_byte[fc]);
                                pu = unit;
                                pf = fc;
                                pfx = fc | 0x80;
                            } else if (ap == FIXED) {
                                pu = unit;
                                pf = fc;
                                pfx = fc | 0x80;
                                pl = (Py_ssize_t)answer_base[fc];
                            } else if (ap == ECHO) {
                                pu = unit;
                                pf = fc;
                                pfx = fc | 0x80;
                                pl = length;
                                pdl = t0 + (double)length * cur_rate + timeout;
                            }
                            if (pl > MAX_RTU) pu = -1;
                        }
                        row += 1;
                        pos = stop;
                        continue;
                    }
                }
            }
            slow = 1; /* the slow path decides at pos */
            goto stopped;
        }
        if (!batch) break;
    }
stopped:;
    /* the reads' spans from the one holding pos on: the timeline forgets what lies
     * before pos (as forget_before does), and nothing asks about it */
    Py_ssize_t first = 0;
    for (Py_ssize_t j = 0; j < n_spans; j++)
        if (spans[j].start <= pos) first = j;
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
                "(OnnnnnnndnnOOOOOOOOnddndndOO)", slow ? Py_True : Py_False, pos, k, prev, end, pu,
                pf, pl, pdl, pr, row, cols[0], cols[1], cols[2], cols[3], cols[4], cols[5],
                cols[6], cols[7], cur_start, cur_t0, cur_rate, offset, last_end, too_fast,
                first_too_fast, span_list, bounds);
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
    return result;
}

static PyMethodDef methods[] = {
    {"crc16", py_crc16, METH_O, "CRC-16/MODBUS of a bytes-like object."},
    {"bulk_epbs", py_bulk_epbs, METH_VARARGS, "pcapng data packets (link types 250, 147) of one batch."},
    {"bulk_pcap", py_bulk_pcap, METH_VARARGS, "Classic pcap data packets of one batch."},
    {"rtu_scan", py_rtu_scan, METH_VARARGS, "The RTU framer's fast paths over reads."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "sniffer._core", "modscope's compiled core (optional).", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__core(void) {
    crc_init();
    return PyModule_Create(&module);
}
