/* SPDX-License-Identifier: MIT */
/*
 * devobj/devobj.c - the device object extension of a line (devobj/devobj.h,
 * docs/devices.md): the mirror's life cycle, the values it receives and
 * their watchers, and the DEV_* commands.
 */
#include "devobj/devobj.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/nmt.h"
#include "core/od.h"
#include "core/pdo.h"
#include "core/sdo.h"
#include "devobj/devobj_int.h"
#include "devobj/mirror.h"
#include "devobj/value.h"
#include "lines/log.h"

struct devobj {
	unsigned n_lines;
	devobj_line lines[DEVOBJ_LINES_MAX];
};

/* ---- the mirror's life cycle ------------------------------------------------ */

static void publish_mirror(devobj_line *dl, uint8_t id)
{
	const devobj_node_mirror *nm = &dl->mirror.node[id];
	const co_pdo_layout_node *ln = co_pdo_layout_node_get(dl->mirror.layout, id);
	unsigned total = ln && ln->valid ? ln->n[0] + ln->n[1] + ln->dropped[0] + ln->dropped[1]
					 : 0;
	mbx_ev_dev_mirror ev = {
		.node = id,
		.status = nm->status,
		.reason = nm->reason,
		.mirrored = (uint16_t)(total - nm->missing),
		.missing = nm->missing,
		.generation = nm->generation,
	};
	if (nm->status == DEVOBJ_M_PARTIAL || nm->status == DEVOBJ_M_NONE)
		cogw_log(COGW_LOG_WARNING,
			 "line %s: node %u: %u of %u PDOs not mirrored (first reason: %s); "
			 "see cogwctl pdo map",
			 dl->p.name, id, nm->missing, total, devobj_reason_to_string(nm->reason));
	else
		cogw_log(COGW_LOG_INFO, "line %s: node %u: mirror %s (%u PDOs)", dl->p.name, id,
			 devobj_mirror_status_to_string(nm->status), total);
	mbx_server_publish(line_mbx(dl->l), MBX_EV_DEV_MIRROR, 0, &ev, sizeof ev);
}

/* A complete frame the device has had goes again (and its deadline is
 * kept again: devobj_write_poll). */
static void resend(devobj_line *dl, devobj_tx *tx)
{
	if (!tx->dirty)
		dl->n_dirty++;
	tx->dirty = true;
	tx->due_us = 0;
	tx->sent = 0;
}

/* Records no longer mirroring what their values and watchers belonged to. */
static void reset_records(devobj_line *dl)
{
	for (unsigned i = 0; i < dl->mirror.n_rec[CO_PDO_RX]; i++) {
		const devobj_record *r = &dl->mirror.rec[CO_PDO_RX][i];
		devobj_rx *rx = &dl->rx[i];
		if (r->busy && rx->node == r->node &&
		    rx->generation == dl->mirror.node[r->node].generation)
			continue;
		memset(rx, 0, sizeof *rx);
		rx->node = r->busy ? r->node : 0;
		rx->generation = r->busy ? dl->mirror.node[r->node].generation : 0;
	}
	for (unsigned i = 0; i < dl->mirror.n_rec[CO_PDO_TX]; i++) {
		const devobj_record *r = &dl->mirror.rec[CO_PDO_TX][i];
		devobj_tx *tx = &dl->tx[i];
		if (r->busy && tx->node == r->node &&
		    tx->generation == dl->mirror.node[r->node].generation) {
			if (tx->resets != dl->mirror.resets && tx->sent)
				resend(dl, tx); /* our reset stopped it: the device waits */
			tx->resets = dl->mirror.resets;
			continue;
		}
		if (tx->dirty)
			dl->n_dirty--; /* its frame belongs to a PDO mirrored no more */
		memset(tx, 0, sizeof *tx);
		tx->resets = dl->mirror.resets;
		tx->node = r->busy ? r->node : 0;
		tx->generation = r->busy ? dl->mirror.node[r->node].generation : 0;
	}
}

/* Whoever changes a layout (the configuration at start-up, the manager's
 * boot step, a boot-up that invalidates it), the mirror follows on the next
 * loop iteration, outside the core's callbacks: one generation compare per
 * mirrored node. */
static void sync_mirrors(devobj_line *dl)
{
	bool changed = false;
	for (unsigned i = 0; i < dl->n_mirrored; i++) {
		uint8_t id = dl->mirrored[i];
		if (devobj_mirror_sync(&dl->mirror, id)) {
			changed = true;
			publish_mirror(dl, id);
		}
	}
	if (changed) {
		reset_records(dl);
		devobj_watch_relink(dl);
		if (dl->p.n_fwd)
			devobj_forward_sources(dl);
	}
}

/* ---- extension ops ------------------------------------------------------------ */

static int devobj_attach(void *ctx, line *l)
{
	devobj_line *dl = ctx;
	int rc;

	dl->l = l;
	rc = devobj_mirror_create(&dl->mirror, line_node(l), line_pdo_layout(l), dl->p.mirror_nodes,
				  dl->p.room_nodes);
	if (rc == -EEXIST)
		cogw_log(COGW_LOG_ERR,
			 "line %s: objects %04Xh/%04Xh are the PDO mirror's slots "
			 "(docs/devices.md): the configuration must not define them",
			 dl->p.name, DEVOBJ_SLOT_RX_INDEX, DEVOBJ_SLOT_TX_INDEX);
	if (rc < 0)
		return rc;
	if ((rc = devobj_watch_init(dl)) < 0)
		return rc;
	unsigned n_rx = dl->mirror.n_rec[CO_PDO_RX], n_tx = dl->mirror.n_rec[CO_PDO_TX];
	dl->rx = calloc(n_rx ? n_rx : 1u, sizeof *dl->rx);
	dl->tx = calloc(n_tx ? n_tx : 1u, sizeof *dl->tx);
	dl->calls = calloc(DEVOBJ_SDO_CALLS, sizeof *dl->calls);
	dl->layout_buf_cap = devobj_layout_answer_max(dl);
	dl->layout_buf = malloc(dl->layout_buf_cap);
	if (!dl->rx || !dl->tx || !dl->calls || !dl->layout_buf)
		return -ENOMEM;
	if (dl->mirror.layout && (n_rx || n_tx))
		cogw_log(COGW_LOG_INFO, "line %s: PDO mirror: %u RPDO and %u TPDO records free",
			 dl->p.name, n_rx, n_tx);
	for (unsigned id = 1; id <= CO_PDO_LAYOUT_NODES; id++)
		if (dl->mirror.node[id].wanted)
			dl->mirrored[dl->n_mirrored++] = (uint8_t)id;
	return 0;
}

static void devobj_detach(void *ctx, line *l)
{
	devobj_line *dl = ctx;
	(void)l;
	devobj_mirror_destroy(&dl->mirror);
	devobj_watch_fini(dl);
	free(dl->rx);
	free(dl->tx);
	free(dl->calls);
	free(dl->layout_buf);
	dl->rx = NULL;
	dl->tx = NULL;
	dl->calls = NULL;
	dl->layout_buf = NULL;
}

static void on_rpdo(devobj_line *dl, const co_ev_pdo *pdo, uint64_t now_us)
{
	const devobj_record *r = devobj_mirror_record_of(&dl->mirror, CO_PDO_RX, pdo->nr);
	if (!r)
		return; /* a hand-written RPDO */
	devobj_rx *rx = &dl->rx[r - dl->mirror.rec[CO_PDO_RX]];
	memcpy(rx->frame, pdo->data, sizeof rx->frame);
	rx->len = pdo->len;
	rx->time_us = now_us;
	rx->count++;
	devobj_watch_received(dl, (unsigned)(r - dl->mirror.rec[CO_PDO_RX]), now_us);
	if (dl->p.n_fwd)
		devobj_forward_received(dl, (unsigned)(r - dl->mirror.rec[CO_PDO_RX]), now_us);
}

static void devobj_on_core_event(void *ctx, line *l, const co_event *ev)
{
	devobj_line *dl = ctx;
	(void)l;
	switch (ev->kind) {
	case CO_EV_RPDO:
		on_rpdo(dl, &ev->u.pdo, ev->now_us);
		return;
	case CO_EV_OBJECT_UPDATED:
		devobj_forward_updated(dl, ev->u.pdo_obj.index, ev->u.pdo_obj.sub);
		return;
	case CO_EV_NMT_STATE:
		/* our own reset communication set the PDO records back to
		 * their defaults (CiA 301 §7.3.2.2.2): program them again */
		if (ev->u.nmt.prev == CO_NMT_INITIALISING)
			devobj_mirror_forget(&dl->mirror);
		return;
	default:
		return;
	}
}

/* A node added, changed or removed at run time (line_node_changed): its
 * mirror follows its "pdo" (its layout, learnt again by its boot, is
 * programmed by sync_mirrors), its objects' types follow its file. */
static void devobj_node_changed(void *ctx, line *l, const line_node_news *in)
{
	devobj_line *dl = ctx;
	bool want = !in->removed && in->pdo == 2;
	unsigned i;
	(void)l;

	dl->p.objects[in->node] = (devobj_node_objects){ .list = in->types, .n = in->n_types };
	if (devobj_mirror_want(&dl->mirror, in->node, want) < 0) {
		cogw_log(COGW_LOG_WARNING,
			 "line %s: node %u: its PDOs cannot be mirrored (no room reserved at "
			 "start-up: the line has no manager or no PDO layout table)",
			 dl->p.name, in->node);
		want = false;
	}
	for (i = 0; i < dl->n_mirrored && dl->mirrored[i] != in->node; i++)
		;
	if (want && i == dl->n_mirrored)
		dl->mirrored[dl->n_mirrored++] = in->node;
	if (!want && i < dl->n_mirrored) {
		dl->mirrored[i] = dl->mirrored[--dl->n_mirrored];
		reset_records(dl);
		devobj_watch_relink(dl);
		publish_mirror(dl, in->node);
	}
}

static void devobj_on_command(void *ctx, line *l, const mbx_request *req)
{
	devobj_line *dl = ctx;
	(void)l;
	switch (req->code) {
	case MBX_CMD_DEV_LAYOUT:
		devobj_cmd_layout(dl, req);
		return;
	case MBX_CMD_DEV_WATCH:
		devobj_cmd_watch(dl, req);
		return;
	case MBX_CMD_DEV_UNWATCH:
		devobj_cmd_unwatch(dl, req);
		return;
	case MBX_CMD_DEV_READ:
		devobj_cmd_read(dl, req);
		return;
	case MBX_CMD_DEV_WRITE:
		devobj_cmd_write(dl, req);
		return;
	case MBX_CMD_DEV_FORWARDS:
		devobj_cmd_forwards(dl, req);
		return;
	}
	mbx_server_respond(line_mbx(l), &req->reply, MBX_E_UNKNOWN_CMD, 0, NULL, 0);
}

static void devobj_on_client_gone(void *ctx, line *l, uint32_t client)
{
	(void)l;
	devobj_watch_client_gone(ctx, client);
}

static uint64_t devobj_poll(void *ctx, line *l, uint64_t now_us)
{
	devobj_line *dl = ctx;
	(void)l;
	sync_mirrors(dl);
	uint64_t next = devobj_watch_poll(dl, now_us);
	uint64_t t = devobj_write_poll(dl, now_us);
	return t < next ? t : next;
}

static const line_ext_ops devobj_ops = {
	.name = "devobj",
	.attach = devobj_attach,
	.detach = devobj_detach,
	.on_core_event = devobj_on_core_event,
	.node_changed = devobj_node_changed,
	.cmd_first = MBX_CMD_DEV_LAYOUT,
	.cmd_last = MBX_CMD_DEV_FORWARDS,
	.on_command = devobj_on_command,
	.on_client_gone = devobj_on_client_gone,
	.poll = devobj_poll,
};

int devobj_create(devobj **out, const devobj_params *p)
{
	*out = NULL;
	if (p->n_lines == 0 || p->n_lines > DEVOBJ_LINES_MAX)
		return -EINVAL;
	devobj *x = calloc(1, sizeof *x);
	if (!x)
		return -ENOMEM;
	x->n_lines = p->n_lines;
	for (unsigned i = 0; i < p->n_lines; i++) {
		x->lines[i].p = p->line[i];
		if (!x->lines[i].p.watches)
			x->lines[i].p.watches = 1;
	}
	*out = x;
	return 0;
}

void devobj_destroy(devobj *x)
{
	free(x);
}

void devobj_line_ext(devobj *x, unsigned line_no, line_ext *out)
{
	out->ops = NULL;
	out->ctx = NULL;
	out->wake_fd = -1;
	if (!x || line_no >= x->n_lines)
		return;
	out->ops = &devobj_ops;
	out->ctx = &x->lines[line_no];
}
