/* SPDX-License-Identifier: MIT */
/*
 * apps/cosim/sim.c - one simulated node: a core instance (core/co.h) with
 * the device's OD, plus what a real device adds around its stack: process
 * values that move (signals), outputs wired back to inputs (loopback),
 * non-volatile memory (1010h/1011h, LSS store), and faults.
 *
 * Faults sit between the core and the bus, so the core stays the one the
 * daemon runs and a test sees the same wire behaviour a broken device
 * would show:
 *   - outgoing frames pass tx_filter(): dropped (silent, heartbeat stop,
 *     SDO silent), held back (SDO delay, a small queue released by tick),
 *     or changed (TPDO one byte short);
 *   - incoming frames pass rx_filter(): ignored (silent), answered in the
 *     core's place (forced SDO abort), or normalised (lenient mode accepts
 *     the too small sizes of printed device sheets, docs/cosim.md).
 */
#include "apps/cosim/cosim.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/emcy.h"
#include "core/heartbeat.h"
#include "core/lss.h"
#include "core/lss_slave.h"
#include "core/nmt.h"
#include "core/pdo.h"
#include "core/sdo.h"
#include "core/store.h"

#define SNAPSHOT_MAX (256u * 1024u)

/* SDO command byte, CiA 301 §7.2.4.3: client command specifier in bits
 * 7..5. Only what the fault filters need to recognise. */
#define SDO_CCS(b) ((uint8_t)((b) >> 5))
enum sdo_ccs_value {
	CCS_DN_SEGMENT = 0,
	CCS_DN_INITIATE = 1,
	CCS_UP_INITIATE = 2,
	CCS_UP_SEGMENT = 3,
	CCS_ABORT = 4,
	CCS_BLK_UPLOAD = 5,
	CCS_BLK_DOWNLOAD = 6,
};
#define SDO_E 0x02u /* expedited */
#define SDO_S 0x01u /* size indicated */

struct delayed {
	co_frame f;
	uint64_t due_us;
};

struct sig_state {
	uint64_t next_us;
	bool override;
	double override_value;
};

struct cosim_node {
	cosim_device dev;
	co_node *node;
	cosim_faults f;
	char nv_dir[256];
	char nv_key[128];
	bool has_nv;
	bool quiet;
	bool autostart;
	bool start_pending;
	cosim_out_fn out;
	void *out_ctx;
	uint64_t start_us;
	uint64_t now_us;
	uint8_t cfg_id;
	uint8_t active_id;

	struct sig_state sig[COSIM_SIGNAL_MAX];

	/* "sdo delay": a ring of held-back answers, released in order */
	struct delayed delay[COSIM_DELAY_QUEUE];
	unsigned delay_head, delay_count;

	/* defaults as the device file defines them: 1011h "load" brings
	 * them back */
	uint8_t *snapshot;
	size_t snapshot_len;

	/* 1010h: core/store.c's hooks, wrapped for the lenient signature */
	const co_od_hooks *store_hooks;
	void *store_ctx;
	co_od_hooks store_wrap;
	lss_slave_hooks lss_hooks;

	uint64_t dropped, delayed_count, forced_aborts;
	cosim_program prog; /* 1F50h/1F51h/1F56h, if the device has them */
};

static void logn(const cosim_node *n, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

static void logn(const cosim_node *n, const char *fmt, ...)
{
	va_list ap;
	char buf[512];

	if (n->quiet)
		return;
	va_start(ap, fmt);
	vsnprintf(buf, sizeof buf, fmt, ap);
	va_end(ap);
	fprintf(stderr, "cosim: node %u (%s): %s\n", n->active_id, n->dev.name, buf);
}

/* ---- numeric values ------------------------------------------------------------ */

static bool entry_numeric(const co_od_entry *e)
{
	return e && !co_type_is_variable((co_type)e->type) && e->size >= 1 && e->size <= 8;
}

static double entry_get(const co_od_entry *e)
{
	uint64_t raw = co_od_entry_raw(e);
	unsigned bits = e->size * 8u;

	if (e->type == CO_T_REAL32) {
		uint32_t b = (uint32_t)raw;
		float f;
		memcpy(&f, &b, sizeof f);
		return f;
	}
	if (e->type == CO_T_REAL64) {
		double d;
		memcpy(&d, &raw, sizeof d);
		return d;
	}
	if (co_type_is_signed((co_type)e->type) && bits < 64 && (raw >> (bits - 1)) & 1)
		return (double)(int64_t)(raw | (~0ULL << bits));
	if (co_type_is_signed((co_type)e->type))
		return (double)(int64_t)raw;
	return (double)raw;
}

/* Store v in a numeric entry, converted to its type (rounded, clamped).
 * Returns true if the value changed. */
static bool entry_set(co_od_entry *e, double v)
{
	uint64_t old = co_od_entry_raw(e), raw;
	unsigned bits = e->size * 8u;

	if (isnan(v))
		v = 0;
	if (e->type == CO_T_REAL32) {
		float f = (float)v;
		uint32_t b;
		memcpy(&b, &f, sizeof b);
		raw = b;
	} else if (e->type == CO_T_REAL64) {
		memcpy(&raw, &v, sizeof raw);
	} else if (e->type == CO_T_BOOLEAN) {
		raw = v != 0;
	} else if (co_type_is_signed((co_type)e->type)) {
		double lo = -ldexp(1, (int)bits - 1), hi = ldexp(1, (int)bits - 1) - 1;
		double r = v < lo ? lo : v > hi ? hi : round(v);
		raw = (uint64_t)(int64_t)r;
		if (bits < 64)
			raw &= ~(~0ULL << bits);
	} else {
		double hi = ldexp(1, (int)bits) - 1;
		double r = v < 0 ? 0 : v > hi ? hi : round(v);
		raw = r >= 18446744073709551615.0 ? UINT64_MAX : (uint64_t)r;
	}
	co_od_entry_set_raw(e, raw);
	return co_od_entry_raw(e) != old;
}

/* ---- signals -------------------------------------------------------------------- */

static double signal_raw(const cosim_node *n, unsigned i, uint64_t now_us)
{
	const cosim_signal_desc *s = &n->dev.signals[i];
	double t, ph;

	if (n->sig[i].override)
		return n->sig[i].override_value;
	if (s->kind == COSIM_SIG_CONST)
		return s->value;
	t = (double)(now_us - n->start_us) / 1000.0;
	ph = fmod(t, (double)s->period_ms) / (double)s->period_ms; /* 0..1 */
	switch (s->kind) {
	case COSIM_SIG_RAMP:
		return s->min + (s->max - s->min) * ph;
	case COSIM_SIG_SINE:
		return (s->min + s->max) / 2 + (s->max - s->min) / 2 * sin(2 * M_PI * ph);
	case COSIM_SIG_SQUARE:
		return ph < 0.5 ? s->min : s->max;
	case COSIM_SIG_CONST:
		break;
	}
	return s->value;
}

static bool loopback_target(const cosim_node *n, uint16_t index, uint8_t sub)
{
	if (!n->dev.loopback_enabled)
		return false;
	for (unsigned i = 0; i < n->dev.n_loopback; i++)
		if (n->dev.loopback[i].to_index == index && n->dev.loopback[i].to_sub == sub)
			return true;
	return false;
}

static void signal_update(cosim_node *n, unsigned i, uint64_t now_us)
{
	const cosim_signal_desc *s = &n->dev.signals[i];
	co_od *od = n->dev.od;
	co_od_entry *e = co_od_find(od, s->index, s->sub);
	double v = signal_raw(n, i, now_us);

	/* An input echoing an output belongs to the loopback while it is on. */
	if (!e || loopback_target(n, s->index, s->sub))
		return;
	if (s->offset_index || s->span_index) {
		/* The transducer's process value (docs/cosim.md): (raw + zero
		 * offset) * span / 100, with the current 2004h:1 / 2005h:1. */
		const co_od_entry *o = s->offset_index
					       ? co_od_find(od, s->offset_index, s->offset_sub)
					       : NULL;
		const co_od_entry *sp = s->span_index ? co_od_find(od, s->span_index, s->span_sub)
						      : NULL;
		double off = entry_numeric(o) ? entry_get(o) : 0.0;
		double span = entry_numeric(sp) ? entry_get(sp) : 100.0;
		v = (v + off) * span / 100.0;
	}
	if (entry_set(e, v) && s->notify)
		co_pdo_object_changed(n->node, s->index, s->sub, now_us);
}

static void signals_run(cosim_node *n, uint64_t now_us)
{
	for (unsigned i = 0; i < n->dev.n_signals; i++) {
		if (now_us < n->sig[i].next_us)
			continue;
		signal_update(n, i, now_us);
		uint64_t step = (uint64_t)n->dev.signals[i].update_ms * 1000u;
		n->sig[i].next_us += step;
		if (n->sig[i].next_us <= now_us)
			n->sig[i].next_us = now_us + step; /* we were late: no burst */
	}
}

/* ---- loopback ------------------------------------------------------------------- */

/* Copy an output written at index:sub into its input(s); with notify,
 * also tell the PDO module that the input changed. */
static void loopback_copy(cosim_node *n, uint16_t index, uint8_t sub, bool notify, uint64_t now_us)
{
	if (!n->dev.loopback_enabled)
		return;
	for (unsigned i = 0; i < n->dev.n_loopback; i++) {
		const cosim_loopback_desc *l = &n->dev.loopback[i];
		if (l->from_index != index || l->from_sub != sub)
			continue;
		co_od_entry *from = co_od_find(n->dev.od, index, sub);
		co_od_entry *to = co_od_find(n->dev.od, l->to_index, l->to_sub);
		if (!entry_numeric(from) || !entry_numeric(to))
			continue;
		co_od_entry_set_raw(to, co_od_entry_raw(from));
		if (notify)
			co_pdo_object_changed(n->node, l->to_index, l->to_sub, now_us);
	}
}

static void loopback_written(cosim_node *n, uint16_t index, uint8_t sub, uint64_t now_us)
{
	loopback_copy(n, index, sub, true, now_us);
}

/* ---- the edge: outgoing frames ------------------------------------------------------ */

static uint32_t sdo_cob(const cosim_node *n, uint8_t sub, uint32_t base)
{
	uint32_t v;

	if (co_od_get_u32(n->dev.od, 0x1200, sub, &v) == 0)
		return (v & 0x80000000u) ? UINT32_MAX : (v & CO_FRAME_SFF_MASK);
	return n->active_id <= 127 ? base + n->active_id : UINT32_MAX;
}

static bool is_tpdo(const cosim_node *n, const co_frame *f)
{
	uint16_t count = co_pdo_count(n->node, CO_PDO_TX);

	if (f->flags & CO_FRAME_RTR)
		return false;
	for (uint16_t nr = 1; nr <= count; nr++) {
		uint32_t cob;
		if (co_od_get_u32(n->dev.od, (uint16_t)(CO_PDO_TPDO_COMM + nr - 1), 1, &cob))
			continue;
		if (cob & CO_PDO_COB_INVALID)
			continue;
		bool ext = (cob & CO_PDO_COB_EXT) != 0;
		if (ext == !!(f->flags & CO_FRAME_EXT) &&
		    (cob & (ext ? CO_FRAME_EFF_MASK : CO_FRAME_SFF_MASK)) == f->id)
			return true;
	}
	return false;
}

static int emit_frame(cosim_node *n, const co_frame *f)
{
	return n->out(n->out_ctx, n, f, n->now_us);
}

static int tx_filter(void *ctx, const co_frame *f)
{
	cosim_node *n = ctx;
	co_frame g;

	if (n->f.silent) {
		n->dropped++;
		return 0;
	}
	/* Heartbeat, not boot-up: a stopped producer still boots. */
	if (n->f.hb_stop && !(f->flags & (CO_FRAME_EXT | CO_FRAME_RTR)) &&
	    f->id == CO_NMT_ERRCTRL_BASE + n->active_id && f->len == 1 && f->data[0] != 0) {
		n->dropped++;
		return 0;
	}
	if (!(f->flags & CO_FRAME_EXT) && f->id == sdo_cob(n, 2, 0x580)) {
		if (n->f.sdo_silent) {
			n->dropped++;
			return 0;
		}
		if (n->f.sdo_delay_ms) {
			if (n->delay_count == COSIM_DELAY_QUEUE) {
				n->dropped++;
				logn(n, "sdo delay queue full: answer dropped");
				return 0;
			}
			struct delayed *d =
				&n->delay[(n->delay_head + n->delay_count) % COSIM_DELAY_QUEUE];
			d->f = *f;
			d->due_us = n->now_us + (uint64_t)n->f.sdo_delay_ms * 1000u;
			n->delay_count++;
			n->delayed_count++;
			return 0;
		}
	}
	if (n->f.pdo_badlen && is_tpdo(n, f)) {
		g = *f;
		if (g.len > 0)
			g.len--;
		else
			g.len = 1;
		return emit_frame(n, &g);
	}
	return emit_frame(n, f);
}

static void delay_run(cosim_node *n, uint64_t now_us)
{
	while (n->delay_count && n->delay[n->delay_head].due_us <= now_us) {
		co_frame f = n->delay[n->delay_head].f;
		n->delay_head = (n->delay_head + 1) % COSIM_DELAY_QUEUE;
		n->delay_count--;
		if (!n->f.silent)
			emit_frame(n, &f);
	}
}

/* ---- the edge: incoming frames --------------------------------------------------------- */

static bool sdo_is_initiate(uint8_t cmd)
{
	switch (SDO_CCS(cmd)) {
	case CCS_DN_INITIATE:
	case CCS_UP_INITIATE:
		return true;
	case CCS_BLK_UPLOAD:
		return (cmd & 0x03) == 0; /* cs 0: initiate */
	case CCS_BLK_DOWNLOAD:
		return (cmd & 0x01) == 0; /* cs 0: initiate */
	default:
		return false;
	}
}

static void send_abort(cosim_node *n, const co_frame *req, uint32_t code)
{
	co_frame a;
	uint32_t cob = sdo_cob(n, 2, 0x580);

	if (cob == UINT32_MAX)
		return;
	co_frame_init(&a, cob, 8);
	a.data[0] = CCS_ABORT << 5;
	memcpy(&a.data[1], &req->data[1], 3); /* multiplexer as requested */
	co_put_le32(&a.data[4], code);
	n->forced_aborts++;
	tx_filter(n, &a);
}

/* Device sheets print 4-byte writes with command 2Bh ("2 bytes",
 * CiA 301 §7.2.4.3.3: n = 2 unused bytes). A
 * lenient device takes the object's own size instead of the indicated
 * one; the strict core would answer 0x06070010. */
static void lenient_size(cosim_node *n, co_frame *f)
{
	uint8_t cmd = f->data[0];

	if (SDO_CCS(cmd) != CCS_DN_INITIATE || (cmd & (SDO_E | SDO_S)) != (SDO_E | SDO_S))
		return;
	unsigned indicated = 4u - ((cmd >> 2) & 3u);
	const co_od_entry *e = co_od_find(n->dev.od, co_get_le16(&f->data[1]), f->data[3]);
	if (!entry_numeric(e) || e->size > 4 || e->size == indicated)
		return;
	f->data[0] = (uint8_t)((CCS_DN_INITIATE << 5) | ((4u - e->size) << 2) | SDO_E | SDO_S);
	logn(n, "lenient: SDO write %04X:%02X says %u bytes, taken as %u", e->index, e->sub,
	     indicated, e->size);
}

void cosim_node_recv(cosim_node *n, const co_frame *f, uint64_t now_us)
{
	co_frame g;

	n->now_us = now_us;
	if (n->f.silent)
		return;
	if (!(f->flags & (CO_FRAME_EXT | CO_FRAME_RTR)) && f->len == 8 &&
	    f->id == sdo_cob(n, 1, 0x600)) {
		uint8_t cmd = f->data[0];
		uint16_t index = co_get_le16(&f->data[1]);
		if (n->f.sdo_abort && sdo_is_initiate(cmd) &&
		    (!n->f.sdo_abort_index ||
		     (index == n->f.sdo_abort_index &&
		      (n->f.sdo_abort_any_sub || f->data[3] == n->f.sdo_abort_sub)))) {
			send_abort(n, f, n->f.sdo_abort);
			return;
		}
		if (n->f.sdo_lenient) {
			g = *f;
			lenient_size(n, &g);
			co_node_recv(n->node, &g, now_us);
			return;
		}
	}
	co_node_recv(n->node, f, now_us);
}

/* ---- store / restore (1010h, 1011h) and LSS store -------------------------------------- */

static unsigned parts_of(uint8_t sub)
{
	switch (sub) {
	case 2:
		return COSIM_NV_COMM;
	case 3:
		return COSIM_NV_APP;
	default:
		return COSIM_NV_COMM | COSIM_NV_APP; /* 1 = all, 4.. = ours: all */
	}
}

static void defaults_from_current(co_od *od, unsigned parts)
{
	for (size_t i = 0; i < co_od_count(od); i++) {
		co_od_entry *e = co_od_at(od, i);
		bool comm = e->index >= 0x1000 && e->index <= 0x1FFF;
		if ((e->access & CO_ACC_CONST) || !(e->access & (CO_ACC_WRITE | CO_ACC_PERSIST)))
			continue;
		if (e->index == CO_STORE_IDX_SAVE || e->index == CO_STORE_IDX_LOAD)
			continue;
		if ((comm && (parts & COSIM_NV_COMM)) || (!comm && (parts & COSIM_NV_APP)))
			co_od_entry_set_default_bytes(e, e->data, e->size);
	}
}

static uint32_t store_save(void *ctx, uint8_t sub, const co_od_access *a)
{
	cosim_node *n = ctx;
	unsigned parts = parts_of(sub);

	(void)a;
	if (n->has_nv) {
		int rc = cosim_nv_save(n->dev.od, n->nv_dir, n->nv_key, parts);
		if (rc) {
			logn(n, "1010h:%02X save to %s/%s failed: %s", sub, n->nv_dir, n->nv_key,
			     strerror(-rc));
			return SDO_AB_STORE;
		}
	}
	/* A reset now comes back to what was saved, as on the real unit. */
	defaults_from_current(n->dev.od, parts);
	logn(n, "1010h:%02X save: %s%s%s", sub, n->has_nv ? n->nv_dir : "in memory only",
	     n->has_nv ? "/" : "", n->has_nv ? n->nv_key : "");
	return 0;
}

static uint32_t store_restore(void *ctx, uint8_t sub, const co_od_access *a)
{
	cosim_node *n = ctx;
	unsigned parts = parts_of(sub), l, s;

	(void)a;
	if (n->has_nv) {
		int rc = cosim_nv_erase(n->nv_dir, n->nv_key, parts);
		if (rc) {
			logn(n, "1011h:%02X restore failed: %s", sub, strerror(-rc));
			return SDO_AB_STORE;
		}
	}
	/* CiA 301 §7.5.2.14: the factory values apply after the next reset,
	 * so only the defaults change now. The snapshot holds both parts;
	 * applying it whole is right for sub 1 and close enough for 2/3. */
	if (n->snapshot)
		co_od_image_apply(n->dev.od, n->snapshot, n->snapshot_len, CO_OD_IMAGE_SET_DEFAULT,
				  &l, &s);
	/* the snapshot holds the device file's flash: the program is no
	 * parameter, keep the one in the device */
	if (n->dev.program.enabled)
		cosim_program_pin(&n->prog);
	logn(n, "1011h:%02X load: device file defaults after the next reset", sub);
	return 0;
}

static const co_store_ops store_ops = {
	.save = store_save,
	.restore = store_restore,
};

/* Device sheets print the 1010h signature reversed ("evas"; CiA 301
 * §7.5.2.13 wants 73 61 76 65). A lenient device
 * accepts it; the core's store hook, which we wrap, sees the right one. */
static uint32_t store_check_wrap(void *ctx, co_od_entry *e, const co_od_access *a)
{
	cosim_node *n = ctx;
	co_od_access b = *a;
	uint8_t sig[4];

	if (n->f.sdo_lenient && e->index == CO_STORE_IDX_SAVE && a->data && a->size == 4 &&
	    co_get_le32(a->data) == 0x73617665u) {
		co_put_le32(sig, CO_STORE_SIG_SAVE);
		b.data = sig;
		logn(n, "lenient: reversed \"save\" signature accepted");
	}
	return n->store_hooks->check_write ? n->store_hooks->check_write(n->store_ctx, e, &b) : 0;
}

static void store_after_wrap(void *ctx, co_od_entry *e, const co_od_access *a)
{
	cosim_node *n = ctx;

	if (n->store_hooks->after_write)
		n->store_hooks->after_write(n->store_ctx, e, a);
}

static int store_setup(cosim_node *n)
{
	uint8_t subs;
	int rc;

	if (co_od_get_u8(n->dev.od, CO_STORE_IDX_SAVE, 0, &subs) || subs == 0)
		return 0; /* the device has no 1010h */
	rc = co_store_attach(n->node, &store_ops, n, subs, CO_STORE_CAP_CMD, CO_STORE_CAP_CMD);
	if (rc)
		return rc;
	for (unsigned s = 1; s <= subs; s++) {
		co_od_entry *e = co_od_find(n->dev.od, CO_STORE_IDX_SAVE, (uint8_t)s);
		if (!e || !e->hooks)
			continue;
		n->store_hooks = e->hooks;
		n->store_ctx = e->hook_ctx;
		n->store_wrap = (co_od_hooks){ .check_write = store_check_wrap,
					       .after_write = store_after_wrap,
					       .read = e->hooks->read };
		co_od_entry_set_hooks(e, &n->store_wrap, n);
	}
	return 0;
}

static uint8_t lss_check_bt(void *ctx, uint8_t table, uint8_t index, uint8_t *spec)
{
	cosim_node *n = ctx;

	(void)spec;
	if (table != LSS_BT_TABLE_CIA || index > 15 ||
	    !(n->dev.lss_bit_timing_mask & (1u << index)))
		return LSS_EC_BIT_TIMING_UNSUPP;
	return LSS_EC_OK;
}

static uint8_t lss_store(void *ctx, uint8_t node_id, bool bt_valid, uint8_t table, uint8_t index,
			 uint8_t *spec)
{
	cosim_node *n = ctx;

	(void)bt_valid;
	(void)table;
	(void)index;
	(void)spec;
	if (n->has_nv) {
		int rc = cosim_nv_save_node_id(n->nv_dir, n->nv_key, node_id);
		if (rc) {
			logn(n, "LSS store of node-ID %u failed: %s", node_id, strerror(-rc));
			return LSS_EC_STORE_ACCESS;
		}
	}
	logn(n, "LSS store: node-ID %u%s", node_id, n->has_nv ? "" : " (in memory only)");
	return LSS_EC_OK;
}

/* ---- core events --------------------------------------------------------------------- */

/* The RPDO events: the loopback, and what went wrong. */
static void on_rpdo_event(cosim_node *n, const co_event *ev)
{
	switch (ev->kind) {
	case CO_EV_RPDO:
		/* After every object of the PDO is written, so that an echoed
		 * TPDO carries all of them, not the first one alone. */
		for (int pass = 0; pass < 2; pass++)
			for (unsigned i = 0; i < ev->u.pdo.n_map && ev->u.pdo.map; i++)
				loopback_copy(n, ev->u.pdo.map[i].index, ev->u.pdo.map[i].sub,
					      pass == 1, ev->now_us);
		break;
	case CO_EV_RPDO_OBJECT:
		if (ev->u.pdo_obj.abort)
			logn(n, "RPDO %u: %04X:%02X refused: %s", ev->u.pdo_obj.nr,
			     ev->u.pdo_obj.index, ev->u.pdo_obj.sub,
			     sdo_abort_to_string(ev->u.pdo_obj.abort));
		break;
	case CO_EV_RPDO_LENGTH:
		logn(n, "RPDO %u: %u bytes, %u mapped: %s", ev->u.pdo.nr, ev->u.pdo.len,
		     ev->u.pdo.mapped_len,
		     ev->u.pdo.fault == CO_PDO_FAULT_SHORT ? "not processed"
							   : "leading bytes used");
		break;
	case CO_EV_RPDO_TIMEOUT:
		logn(n, "RPDO %u: event timer ran out", ev->u.pdo.nr);
		break;
	default:
		break;
	}
}

/* The LSS slave's events: its state, a new node-ID, a bit timing. */
static void on_lss_event(cosim_node *n, const co_event *ev)
{
	switch (ev->kind) {
	case CO_EV_LSS_SLAVE_STATE:
		logn(n, "LSS %s", lss_state_to_string((lss_state)ev->u.lss_slave.state));
		break;
	case CO_EV_LSS_SLAVE_NODE_ID:
		if (ev->u.lss_slave.active_id != n->active_id) {
			/* Called inside reset communication, after the OD went back
			 * to its defaults and before SDO/EMCY/PDO read it: move the
			 * "+node-ID" COB-IDs along (CiA 301 §7.3.5). */
			logn(n, "LSS: node-ID %u -> %u", n->active_id, ev->u.lss_slave.active_id);
			n->active_id = ev->u.lss_slave.active_id;
			cosim_device_rebase(&n->dev, n->dev.od, n->active_id);
		} else {
			logn(n, "LSS: pending node-ID %u", ev->u.lss_slave.pending_id);
		}
		break;
	case CO_EV_LSS_SLAVE_BIT_TIMING:
		logn(n, "LSS: activate bit timing table %u index %u after %u ms (vcan: no-op)",
		     ev->u.lss_slave.bt_table, ev->u.lss_slave.bt_index, ev->u.lss_slave.delay_ms);
		break;
	default:
		break;
	}
}

static void on_event(void *ctx, const co_event *ev)
{
	cosim_node *n = ctx;

	switch (ev->kind) {
	case CO_EV_NMT_STATE:
		logn(n, "NMT %s -> %s", co_nmt_state_to_string(ev->u.nmt.prev),
		     co_nmt_state_to_string(ev->u.nmt.state));
		if (n->autostart && ev->u.nmt.state == CO_NMT_PRE_OPERATIONAL &&
		    ev->u.nmt.prev == CO_NMT_INITIALISING)
			n->start_pending = true;
		break;
	case CO_EV_OD_WRITTEN:
		logn(n, "SDO write %04X:%02X (%u bytes)", ev->u.od.index, ev->u.od.sub,
		     ev->u.od.size);
		loopback_written(n, ev->u.od.index, ev->u.od.sub, ev->now_us);
		break;
	case CO_EV_RPDO:
	case CO_EV_RPDO_OBJECT:
	case CO_EV_RPDO_LENGTH:
	case CO_EV_RPDO_TIMEOUT:
		on_rpdo_event(n, ev);
		break;
	case CO_EV_SDO_SERVER_DONE:
		if (ev->u.sdo_srv.abort)
			logn(n, "SDO %s %04X:%02X aborted: %08X (%s)",
			     ev->u.sdo_srv.upload ? "upload" : "download", ev->u.sdo_srv.index,
			     ev->u.sdo_srv.sub, ev->u.sdo_srv.abort,
			     sdo_abort_to_string(ev->u.sdo_srv.abort));
		break;
	case CO_EV_LSS_SLAVE_STATE:
	case CO_EV_LSS_SLAVE_NODE_ID:
	case CO_EV_LSS_SLAVE_BIT_TIMING:
		on_lss_event(n, ev);
		break;
	case CO_EV_TX_FAILED:
		logn(n, "frame %03X not sent (tx queue full)", ev->u.frame.id);
		break;
	default:
		break;
	}
}

/* ---- lifetime ---------------------------------------------------------------------- */

/* The device file's values, before anything stored replaces them. */
static void take_snapshot(cosim_node *n)
{
	long len;

	n->snapshot = malloc(SNAPSHOT_MAX);
	if (!n->snapshot)
		return;
	len = co_od_image_write(n->dev.od, COSIM_NV_COMM | COSIM_NV_APP, n->snapshot, SNAPSHOT_MAX);
	if (len < 0) {
		free(n->snapshot);
		n->snapshot = NULL;
	} else {
		n->snapshot_len = (size_t)len;
	}
}

/* The stored LSS node-ID and values, when the node has a store. */
static int load_stored(cosim_node *n, char *err, size_t errlen)
{
	unsigned loaded = 0, skipped = 0;
	uint8_t stored;
	int rc;

	if (!n->has_nv)
		return 0;
	if (n->dev.lss_enabled && !n->dev.lss_constant_id &&
	    cosim_nv_load_node_id(n->nv_dir, n->nv_key, &stored) == 0 && stored != n->active_id) {
		logn(n, "LSS node-ID %u from %s/%s.lss", stored, n->nv_dir, n->nv_key);
		n->active_id = stored;
		cosim_device_rebase(&n->dev, n->dev.od, stored);
	}
	rc = cosim_nv_load(n->dev.od, n->nv_dir, n->nv_key, &loaded, &skipped);
	if (rc) {
		snprintf(err, errlen, "%s: cannot read stored values in %s: %s", n->dev.file,
			 n->nv_dir, strerror(-rc));
		return rc;
	}
	if (loaded || skipped)
		logn(n, "%u stored values loaded from %s/%s.*%s", loaded, n->nv_dir, n->nv_key,
		     skipped ? " (some records skipped)" : "");
	return 0;
}

/* The core instance of the node, its store and program objects hooked. */
static int start_core(cosim_node *n, uint32_t sdo_timeout_ms, char *err, size_t errlen)
{
	co_node_config nc;
	int rc;

	memset(&nc, 0, sizeof nc);
	nc.node_id = n->active_id;
	nc.od = n->dev.od;
	nc.send = tx_filter;
	nc.send_ctx = n;
	nc.event = on_event;
	nc.event_ctx = n;
	nc.lss_slave = n->dev.lss_enabled;
	nc.lss_slave_constant_id = n->dev.lss_constant_id;
	nc.sdo_server_timeout_ms = sdo_timeout_ms;
	n->lss_hooks.store = lss_store;
	if (n->dev.lss_bit_timing_mask)
		n->lss_hooks.check_bit_timing = lss_check_bt;
	nc.lss_slave_hooks = &n->lss_hooks;
	nc.lss_slave_ctx = n;
	rc = co_node_create(&n->node, &nc);
	if (rc) {
		snprintf(err, errlen, "%s: cannot create the node: %s", n->dev.file, strerror(-rc));
		return rc;
	}
	rc = store_setup(n);
	if (rc) {
		snprintf(err, errlen, "%s: cannot attach 1010h/1011h: %s", n->dev.file,
			 strerror(-rc));
		return rc;
	}
	if (n->dev.program.enabled &&
	    (rc = cosim_program_attach(&n->prog, n->dev.od, &n->dev.program, n->cfg_id,
				       n->quiet))) {
		snprintf(err, errlen, "%s: cannot attach 1F50h/1F51h: %s", n->dev.file,
			 strerror(-rc));
		return rc;
	}
	return 0;
}

int cosim_node_create(cosim_node **out, const cosim_node_config *cfg, char *err, size_t errlen)
{
	cosim_node *n = calloc(1, sizeof *n);
	int rc;

	if (!n) {
		cosim_device_free(cfg->dev);
		return -ENOMEM;
	}
	n->dev = *cfg->dev; /* takes the OD */
	memset(cfg->dev, 0, sizeof *cfg->dev);
	n->f = cfg->faults;
	n->quiet = cfg->quiet;
	n->autostart = cfg->autostart;
	n->out = cfg->out;
	n->out_ctx = cfg->out_ctx;
	n->start_us = n->now_us = cfg->now_us;
	n->cfg_id = n->active_id = n->dev.node_id;
	if (cfg->nv_dir) {
		n->has_nv = true;
		snprintf(n->nv_dir, sizeof n->nv_dir, "%s", cfg->nv_dir);
		snprintf(n->nv_key, sizeof n->nv_key, "%s", cfg->nv_key);
	}
	take_snapshot(n);
	if ((rc = load_stored(n, err, errlen)) ||
	    (rc = start_core(n, cfg->sdo_timeout_ms, err, errlen))) {
		cosim_node_destroy(n);
		return rc;
	}
	for (unsigned i = 0; i < n->dev.n_signals; i++)
		n->sig[i].next_us = cfg->now_us;
	*out = n;
	return 0;
}

void cosim_node_destroy(cosim_node *n)
{
	if (!n)
		return;
	co_node_destroy(n->node); /* before the OD it uses */
	cosim_device_free(&n->dev);
	free(n->snapshot);
	free(n);
}

uint64_t cosim_node_tick(cosim_node *n, uint64_t now_us)
{
	n->now_us = now_us;
	signals_run(n, now_us);
	co_node_tick(n->node, now_us);
	if (n->start_pending) {
		n->start_pending = false;
		if (co_nmt_get_state(n->node) == CO_NMT_PRE_OPERATIONAL)
			co_nmt_local_cmd(n->node, CO_NMT_CS_START, now_us);
	}
	delay_run(n, now_us);
	return cosim_node_next_deadline(n);
}

uint64_t cosim_node_next_deadline(const cosim_node *n)
{
	uint64_t t = co_node_next_deadline_us(n->node);

	if (n->start_pending)
		return 0;
	for (unsigned i = 0; i < n->dev.n_signals; i++)
		if (n->sig[i].next_us < t)
			t = n->sig[i].next_us;
	if (n->delay_count && n->delay[n->delay_head].due_us < t)
		t = n->delay[n->delay_head].due_us;
	return t;
}

uint8_t cosim_node_config_id(const cosim_node *n)
{
	return n->cfg_id;
}

co_node *cosim_node_core(const cosim_node *n)
{
	return n->node;
}

cosim_faults *cosim_node_faults(cosim_node *n)
{
	return &n->f;
}

/* ---- control commands ---------------------------------------------------------------- */

static int on_off(const char *w, bool *out)
{
	if (w && (!strcmp(w, "on") || !strcmp(w, "stop") || !strcmp(w, "1"))) {
		*out = true;
		return 0;
	}
	if (w && (!strcmp(w, "off") || !strcmp(w, "start") || !strcmp(w, "0"))) {
		*out = false;
		return 0;
	}
	return -EINVAL;
}

static bool parse_u32(const char *w, uint32_t *v)
{
	char *end;
	unsigned long long x;

	if (!w || !*w)
		return false;
	errno = 0;
	x = strtoull(w, &end, 0);
	if (errno || *end || x > UINT32_MAX)
		return false;
	*v = (uint32_t)x;
	return true;
}

static bool parse_double(const char *w, double *v)
{
	char *end;

	if (!w || !*w)
		return false;
	*v = strtod(w, &end);
	return !*end && isfinite(*v);
}

static int reply_err(char *reply, size_t len, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));
static int reply_err(char *reply, size_t len, const char *fmt, ...)
{
	va_list ap;
	int k = snprintf(reply, len, "error: ");

	va_start(ap, fmt);
	if (k > 0 && (size_t)k < len)
		vsnprintf(reply + k, len - (size_t)k, fmt, ap);
	va_end(ap);
	return -EINVAL;
}

static int find_signal(const cosim_node *n, const char *name)
{
	for (unsigned i = 0; i < n->dev.n_signals; i++)
		if (!strcmp(n->dev.signals[i].name, name))
			return (int)i;
	return -1;
}

static int cmd_signal(cosim_node *n, int i, const char *val, uint64_t now_us, char *reply,
		      size_t rl)
{
	double v;

	if (val && !strcmp(val, "off")) {
		n->sig[i].override = false;
	} else if (parse_double(val, &v)) {
		n->sig[i].override = true;
		n->sig[i].override_value = v;
	} else {
		return reply_err(reply, rl, "expected a number or \"off\"");
	}
	/* Apply now, so that the next PDO or SDO read already has it. */
	signal_update(n, (unsigned)i, now_us);
	const cosim_signal_desc *s = &n->dev.signals[i];
	const co_od_entry *e = co_od_find(n->dev.od, s->index, s->sub);
	snprintf(reply, rl, "ok %04X:%02X = %g", s->index, s->sub, e ? entry_get(e) : 0.0);
	return 0;
}

static int cmd_sdo(cosim_node *n, char **w, int nw, char *reply, size_t rl)
{
	uint32_t v;

	if (nw >= 3 && !strcmp(w[1], "silent") && !on_off(w[2], &n->f.sdo_silent))
		return snprintf(reply, rl, "ok sdo silent %s", n->f.sdo_silent ? "on" : "off"), 0;
	if (nw >= 3 && !strcmp(w[1], "lenient") && !on_off(w[2], &n->f.sdo_lenient))
		return snprintf(reply, rl, "ok sdo lenient %s", n->f.sdo_lenient ? "on" : "off"), 0;
	if (nw >= 3 && !strcmp(w[1], "delay") && parse_u32(w[2], &v)) {
		n->f.sdo_delay_ms = v;
		return snprintf(reply, rl, "ok sdo delay %u ms", v), 0;
	}
	if (nw >= 3 && !strcmp(w[1], "abort")) {
		if (!strcmp(w[2], "off")) {
			n->f.sdo_abort = 0;
			return snprintf(reply, rl, "ok sdo abort off"), 0;
		}
		if (!parse_u32(w[2], &v) || v == 0)
			return reply_err(reply, rl,
					 "sdo abort wants a code like 0x06060000 or off");
		uint16_t index = 0;
		uint8_t sub = 0;
		bool any = true;
		if (nw >= 4) {
			if (cosim_parse_object(w[3], &index, &sub))
				return reply_err(reply, rl, "bad object \"%s\" (0xINDEX[:SUB])",
						 w[3]);
			any = !strchr(w[3], ':');
		}
		n->f.sdo_abort = v;
		n->f.sdo_abort_index = index;
		n->f.sdo_abort_sub = sub;
		n->f.sdo_abort_any_sub = any;
		return snprintf(reply, rl, "ok sdo abort %08X (%s)", v, sdo_abort_to_string(v)), 0;
	}
	return reply_err(
		reply, rl,
		"sdo silent on|off, sdo abort CODE [OBJECT]|off, sdo delay MS, sdo lenient on|off");
}

static int cmd_nmt(cosim_node *n, const char *w, uint64_t now_us, char *reply, size_t rl)
{
	static const struct {
		const char *word;
		uint8_t cs;
	} words[] = { { "start", CO_NMT_CS_START },
		      { "stop", CO_NMT_CS_STOP },
		      { "preop", CO_NMT_CS_ENTER_PREOP },
		      { "reset-node", CO_NMT_CS_RESET_NODE },
		      { "reset-comm", CO_NMT_CS_RESET_COMM } };

	for (size_t i = 0; w && i < sizeof words / sizeof words[0]; i++) {
		if (strcmp(w, words[i].word))
			continue;
		int rc = co_nmt_local_cmd(n->node, words[i].cs, now_us);
		if (rc)
			return reply_err(reply, rl, "nmt %s: %s", w, strerror(-rc));
		return snprintf(reply, rl, "ok nmt %s",
				co_nmt_state_to_string(co_nmt_get_state(n->node))),
		       0;
	}
	return reply_err(reply, rl, "nmt start|stop|preop|reset-node|reset-comm");
}

static int cmd_set_get(cosim_node *n, char **w, int nw, uint64_t now_us, char *reply, size_t rl)
{
	uint16_t index;
	uint8_t sub;
	double v;
	co_od_entry *e;

	if (nw < 2 || cosim_parse_object(w[1], &index, &sub))
		return reply_err(reply, rl, "%s 0xINDEX:SUB%s", w[0],
				 !strcmp(w[0], "set") ? " VALUE" : "");
	e = co_od_find(n->dev.od, index, sub);
	if (!e)
		return reply_err(reply, rl, "object %04X:%02X does not exist", index, sub);
	if (!strcmp(w[0], "get")) {
		if (entry_numeric(e))
			return snprintf(reply, rl, "ok %04X:%02X = %.9g", index, sub, entry_get(e)),
			       0;
		return snprintf(reply, rl, "ok %04X:%02X = \"%.*s\"", index, sub, (int)e->size,
				(const char *)e->data),
		       0;
	}
	if (nw < 3)
		return reply_err(reply, rl, "set 0xINDEX:SUB VALUE");
	if (entry_numeric(e)) {
		if (!parse_double(w[2], &v))
			return reply_err(reply, rl, "\"%s\" is not a number", w[2]);
		entry_set(e, v);
	} else if (co_od_entry_set_bytes(e, w[2], (uint32_t)strlen(w[2]))) {
		return reply_err(reply, rl, "value too long for %04X:%02X", index, sub);
	}
	co_pdo_object_changed(n->node, index, sub, now_us);
	loopback_written(n, index, sub, now_us);
	return snprintf(reply, rl, "ok %04X:%02X set", index, sub), 0;
}

static int cmd_status(cosim_node *n, char *reply, size_t rl)
{
	snprintf(reply, rl, "ok node %u state %s%s%s%s%s%s%s dropped %llu delayed %llu aborts %llu",
		 n->active_id, co_nmt_state_to_string(co_nmt_get_state(n->node)),
		 n->f.silent ? " silent" : "", n->f.hb_stop ? " hb-stop" : "",
		 n->f.sdo_silent ? " sdo-silent" : "", n->f.sdo_abort ? " sdo-abort" : "",
		 n->f.sdo_delay_ms ? " sdo-delay" : "", n->f.pdo_badlen ? " pdo-badlen" : "",
		 (unsigned long long)n->dropped, (unsigned long long)n->delayed_count,
		 (unsigned long long)n->forced_aborts);
	return 0;
}

/* A control command's words w[0..nw-1] (nw >= 1) carried out, its answer
 * in reply; NOT_MINE when the words do not fit it (then the command is
 * unknown). The time is n->now_us. */
#define NOT_MINE 1
typedef int (*node_cmd_fn)(cosim_node *n, char **w, int nw, char *reply, size_t rl);

static int cmd_hb(cosim_node *n, char **w, int nw, char *reply, size_t rl)
{
	bool b;

	if (nw < 2 || on_off(w[1], &b))
		return NOT_MINE;
	n->f.hb_stop = b;
	logn(n, "fault: heartbeat %s", b ? "stopped" : "running");
	return snprintf(reply, rl, "ok hb %s", b ? "stop" : "start"), 0;
}

static int cmd_silent(cosim_node *n, char **w, int nw, char *reply, size_t rl)
{
	bool b;

	if (nw < 2 || on_off(w[1], &b))
		return NOT_MINE;
	n->f.silent = b;
	logn(n, "fault: %s", b ? "silent (cable pulled)" : "back on the bus");
	return snprintf(reply, rl, "ok silent %s", b ? "on" : "off"), 0;
}

static int cmd_sdo_fault(cosim_node *n, char **w, int nw, char *reply, size_t rl)
{
	int rc = cmd_sdo(n, w, nw, reply, rl);

	if (!rc)
		logn(n, "fault: %s", reply + 3);
	return rc;
}

static int cmd_pdo(cosim_node *n, char **w, int nw, char *reply, size_t rl)
{
	bool b;

	if (nw < 3 || strcmp(w[1], "badlen") || on_off(w[2], &b))
		return NOT_MINE;
	n->f.pdo_badlen = b;
	logn(n, "fault: TPDO wrong length %s", b ? "on" : "off");
	return snprintf(reply, rl, "ok pdo badlen %s", b ? "on" : "off"), 0;
}

static int cmd_emcy(cosim_node *n, char **w, int nw, char *reply, size_t rl)
{
	uint32_t v, reg = 0;
	int rc;

	if (nw < 2)
		return NOT_MINE;
	if (!strcmp(w[1], "clear")) {
		rc = co_emcy_clear_all(n->node, n->now_us);
	} else {
		if (!parse_u32(w[1], &v) || v == 0 || v > 0xFFFF ||
		    (nw >= 3 && (!parse_u32(w[2], &reg) || reg > 0xFF)))
			return reply_err(reply, rl, "emcy CODE [REGISTER] | emcy clear");
		rc = co_emcy_send(n->node, (uint16_t)v, (uint8_t)reg, NULL, n->now_us);
	}
	if (rc && rc != -ENOSPC)
		return reply_err(reply, rl, "emcy: %s", strerror(-rc));
	logn(n, "EMCY %s", w[1]);
	return snprintf(reply, rl, "ok emcy %s", w[1]), 0;
}

/* "pressure [VALUE]" (the signal of that name) or "signal NAME [VALUE]". */
static int cmd_signal_word(cosim_node *n, char **w, int nw, char *reply, size_t rl)
{
	bool named = !strcmp(w[0], "signal");
	const char *name = named ? (nw >= 2 ? w[1] : "") : "pressure";
	int i = find_signal(n, name);

	if (i < 0)
		return reply_err(reply, rl, "this device has no signal \"%s\"", name);
	return cmd_signal(n, i, nw > (named ? 2 : 1) ? w[named ? 2 : 1] : NULL, n->now_us, reply,
			  rl);
}

static int cmd_loopback(cosim_node *n, char **w, int nw, char *reply, size_t rl)
{
	bool b;

	if (nw < 2 || on_off(w[1], &b))
		return NOT_MINE;
	n->dev.loopback_enabled = b;
	return snprintf(reply, rl, "ok loopback %s", b ? "on" : "off"), 0;
}

static int cmd_set_get_word(cosim_node *n, char **w, int nw, char *reply, size_t rl)
{
	return cmd_set_get(n, w, nw, n->now_us, reply, rl);
}

static int cmd_nmt_word(cosim_node *n, char **w, int nw, char *reply, size_t rl)
{
	return cmd_nmt(n, nw >= 2 ? w[1] : NULL, n->now_us, reply, rl);
}

static int cmd_status_word(cosim_node *n, char **w, int nw, char *reply, size_t rl)
{
	(void)w;
	(void)nw;
	return cmd_status(n, reply, rl);
}

static const struct {
	const char *word;
	node_cmd_fn run;
} node_cmds[] = {
	{ "hb", cmd_hb },
	{ "silent", cmd_silent },
	{ "sdo", cmd_sdo_fault },
	{ "pdo", cmd_pdo },
	{ "emcy", cmd_emcy },
	{ "pressure", cmd_signal_word },
	{ "signal", cmd_signal_word },
	{ "loopback", cmd_loopback },
	{ "set", cmd_set_get_word },
	{ "get", cmd_set_get_word },
	{ "nmt", cmd_nmt_word },
	{ "status", cmd_status_word },
};

int cosim_node_command(cosim_node *n, const char *line, uint64_t now_us, char *reply, size_t rl)
{
	char buf[256], *w[8], *save = NULL;
	int nw = 0;

	n->now_us = now_us;
	snprintf(buf, sizeof buf, "%s", line);
	for (char *t = strtok_r(buf, " \t\r\n", &save); t && nw < 8;
	     t = strtok_r(NULL, " \t\r\n", &save))
		w[nw++] = t;
	if (nw == 0)
		return reply_err(reply, rl, "empty command");
	for (size_t i = 0; i < sizeof node_cmds / sizeof node_cmds[0]; i++) {
		int rc;

		if (strcmp(w[0], node_cmds[i].word))
			continue;
		rc = node_cmds[i].run(n, w, nw, reply, rl);
		if (rc != NOT_MINE)
			return rc;
		break;
	}
	return reply_err(reply, rl, "unknown command \"%s\" (see cosim --help)", w[0]);
}
