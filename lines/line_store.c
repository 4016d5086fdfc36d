/* SPDX-License-Identifier: MIT */
/*
 * lines/line_store.c - 1010h "save" / 1011h "load" of one line, persisted
 * under the state directory.
 *
 * The line thread never does file I/O: on "save" it serialises the values
 * into a buffer allocated at start-up, parks the SDO answer (a deferred
 * answer, core/store.h) and wakes the main thread, which writes the file
 * atomically (temp file, fsync, rename, fsync of the directory) and wakes
 * the line again; only then does the client get its confirmation, or
 * 0x08000020 if the write failed. A power cut leaves the old file or the
 * new one, never a torn one.
 *
 * What is saved (CiA 301 §7.5.2.13): sub 2 = communication objects
 * (1000h-1FFFh), sub 3 = application objects (2000h-FFFFh), sub 1 = both;
 * each part in its own file <line>.comm / <line>.app, so saving one part
 * keeps the other. Only entries that can change are written: writable
 * ones, and those flagged persistent. 1011h "load" deletes the files, so
 * the next start brings the configured values back.
 *
 * What a reset brings back (CiA 301 §7.5.2.13/14): NMT reset node
 * (application) and reset communication set the objects to their
 * defaults (core/od.h), so the defaults are kept equal to what is stored:
 * - at start-up, loaded values become the defaults too;
 * - a successful "save" makes the saved values the defaults of its parts
 *   at once (not only at the next start);
 * - a successful "load" makes the configured values (an image taken at
 *   start-up before any file was loaded) the defaults of its parts again,
 *   so the next reset node (sub 1..3) or reset communication (sub 1, 2)
 *   brings the defaults back. Current values stay until that reset.
 *
 * The files hold core/od_image.h images (the simulator uses the same
 * format). On load every record is checked against the OD and bad ones are
 * skipped and counted in the log line, never trusted.
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include "core/od_image.h"
#include "core/sdo_server.h"
#include "core/store.h"
#include "lines/file_atomic.h"
#include "lines/log.h"

/* Each part in its own file; the save buffer holds the parts one after the
 * other, each prefixed with its length. */
static const unsigned parts[] = { CO_OD_IMAGE_COMM, CO_OD_IMAGE_APP };
#define N_PARTS 2

/* 1010h/1011h sub-index -> the parts it covers (CiA 301 §7.5.2.13). */
static unsigned parts_of_sub(uint8_t sub)
{
	return sub == 2 ? CO_OD_IMAGE_COMM : sub == 3 ? CO_OD_IMAGE_APP : CO_OD_IMAGE_COMM | CO_OD_IMAGE_APP;
}

static long write_parts(const co_od *od, unsigned parts_mask, uint8_t *buf, uint32_t cap);

static void part_path(const line *l, unsigned part, char *out, size_t len)
{
	snprintf(out, len, "%s.%s", l->state_path, part == CO_OD_IMAGE_COMM ? "comm" : "app");
}

/* Hand the request to the main thread, which does the file I/O. */
static void request_main(line *l, uint8_t op, uint8_t sub, const co_od_access *a)
{
	l->store.op = op;
	l->store.sub = sub;
	l->store.from_sdo = a->origin == CO_OD_ORIGIN_SDO;
	l->store.channel = a->channel;
	atomic_store(&l->store.state, 1);
	if (l->p.main_wakefd >= 0)
		eventfd_write(l->p.main_wakefd, 1);
}

static uint32_t on_save(void *ctx, uint8_t sub, const co_od_access *a)
{
	line *l = ctx;
	if (sub > 3)
		return 0x08000020u; /* manufacturer parts: nothing defined */
	if (atomic_load(&l->store.state) != 0)
		return 0x08000022u; /* one save at a time: "device state" */
	/* serialise now, on the line thread: the OD is only ever read here */
	long n = write_parts(co_node_od(l->node), parts_of_sub(sub), l->store.blob, LINE_STORE_MAX);
	if (n < 0) {
		cogw_log(COGW_LOG_ERR, "line %s: save: values exceed %u bytes", l->name, LINE_STORE_MAX);
		return 0x08000020u;
	}
	l->store.len = (uint32_t)n;
	request_main(l, 1, sub, a);
	return a->origin == CO_OD_ORIGIN_SDO ? CO_OD_DEFERRED : 0;
}

static uint32_t on_restore(void *ctx, uint8_t sub, const co_od_access *a)
{
	line *l = ctx;
	if (sub > 3)
		return 0x08000020u;
	if (atomic_load(&l->store.state) != 0)
		return 0x08000022u;
	l->store.len = 0;
	request_main(l, 2, sub, a);
	return a->origin == CO_OD_ORIGIN_SDO ? CO_OD_DEFERRED : 0;
}

static const co_store_ops store_ops = { .save = on_save, .restore = on_restore };

int line_store_attach(line *l)
{
	int rc = co_store_attach(l->node, &store_ops, l, 3, CO_STORE_CAP_CMD, CO_STORE_CAP_CMD);
	if (rc < 0 && rc != -EEXIST)
		cogw_log(COGW_LOG_ERR, "line %s: cannot attach 1010h/1011h: %s", l->name, strerror(-rc));
	return rc == -EEXIST ? 0 : rc;
}

int line_store_request_mbx(line *l, uint8_t op, uint8_t sub, const mbx_reply_to *to)
{
	if (sub < 1 || sub > 3 || (op != 1 && op != 2))
		return -EINVAL;
	co_od_access a = { .origin = CO_OD_ORIGIN_LOCAL };
	uint32_t abort = op == 1 ? on_save(l, sub, &a) : on_restore(l, sub, &a);
	if (abort == 0x08000022u)
		return -EBUSY;
	if (abort)
		return -EIO;
	l->store.reply = *to;
	return 0;
}

/* ---- main thread ---------------------------------------------------------- */

bool line_store_service(line *l)
{
	if (!l || atomic_load(&l->store.state) != 1)
		return false;
	int rc = 0;
	char path[400];
	uint32_t off = 0;
	for (int i = 0; i < N_PARTS && !rc; i++) {
		if (!(parts_of_sub(l->store.sub) & parts[i]))
			continue;
		part_path(l, parts[i], path, sizeof path);
		if (l->store.op == 1) {
			uint32_t n = co_get_le32(l->store.blob + off);
			rc = file_write_atomic(path, l->store.blob + off + 4, n, 0640);
			off += 4u + n;
		} else if (unlink(path) != 0 && errno != ENOENT) {
			rc = -errno;
		}
	}
	if (rc)
		cogw_log(COGW_LOG_ERR, "line %s: %s %s: %s", l->name,
			 l->store.op == 1 ? "save to" : "restore (delete)", path, strerror(-rc));
	else
		cogw_log(COGW_LOG_INFO, "line %s: %s (%s sub %u)", l->name,
			 l->store.op == 1 ? "parameters saved" : "defaults restored for the next reset or start",
			 l->store.op == 1 ? "1010h" : "1011h", l->store.sub);
	l->store.result = rc;
	atomic_store(&l->store.state, 2);
	line_wake(l);
	return true;
}

/* ---- line thread ---------------------------------------------------------- */

/* Serialise the parts of `parts_mask` of the OD into buf as the save blob
 * lays them out (each part prefixed with its length; parts not in the
 * mask are skipped). Returns the length or -EMSGSIZE. */
static long write_parts(const co_od *od, unsigned parts_mask, uint8_t *buf, uint32_t cap)
{
	uint32_t off = 0;
	for (int i = 0; i < N_PARTS; i++) {
		if (!(parts_mask & parts[i]))
			continue;
		if (cap - off < 4)
			return -EMSGSIZE;
		long n = co_od_image_write(od, parts[i], buf + off + 4, cap - off - 4);
		if (n < 0)
			return n;
		co_put_le32(buf + off, (uint32_t)n);
		off += 4u + (uint32_t)n;
	}
	return off;
}

/* Make the values of a blob (as write_parts() lays it out) the defaults of
 * the entries it holds, restricted to the parts of `parts_mask`; the
 * current values stay. */
static void set_defaults_from(line *l, const uint8_t *buf, uint32_t len, unsigned parts_mask,
			      unsigned buf_parts)
{
	uint32_t off = 0;
	for (int i = 0; i < N_PARTS && off + 4 <= len; i++) {
		if (!(buf_parts & parts[i]))
			continue;
		uint32_t n = co_get_le32(buf + off);
		if (n > len - off - 4)
			return;
		if (parts_mask & parts[i]) {
			unsigned applied, skipped;
			co_od_image_apply(co_node_od(l->node), buf + off + 4, n, CO_OD_IMAGE_SET_DEFAULT,
					  &applied, &skipped);
		}
		off += 4u + n;
	}
}

void line_store_poll(line *l)
{
	if (atomic_load(&l->store.state) != 2)
		return;
	if (!l->store.result) {
		unsigned mask = parts_of_sub(l->store.sub);
		if (l->store.op == 1)
			set_defaults_from(l, l->store.blob, l->store.len, mask, mask);
		else if (l->store.factory)
			set_defaults_from(l, l->store.factory, l->store.factory_len, mask,
					  CO_OD_IMAGE_COMM | CO_OD_IMAGE_APP);
	}
	uint32_t abort = l->store.result ? 0x08000020u : 0;
	if (l->store.from_sdo)
		sdo_server_continue(l->node, l->store.channel, abort, NULL, 0, l->now_us);
	else
		mbx_server_respond(l->mbx, &l->store.reply, l->store.result ? MBX_E_INTERNAL : 0, 0, NULL, 0);
	atomic_store(&l->store.state, 0);
}

/* Start-up, before the node is created (its services read their objects
 * when they start) and before the thread runs, so plain file I/O is fine. */
static void load_part(line *l, unsigned part)
{
	char path[400];
	part_path(l, part, path, sizeof path);
	FILE *f = fopen(path, "rb");
	if (!f) {
		if (errno != ENOENT)
			cogw_log(COGW_LOG_WARNING, "line %s: cannot read %s: %s", l->name, path, strerror(errno));
		return;
	}
	size_t n = fread(l->store.blob, 1, LINE_STORE_MAX, f);
	fclose(f);
	unsigned applied, skipped;
	if (co_od_image_apply(l->p.node.od, l->store.blob, n,
			      CO_OD_IMAGE_SET_VALUE | CO_OD_IMAGE_SET_DEFAULT, &applied, &skipped) < 0) {
		cogw_log(COGW_LOG_WARNING, "line %s: %s is not a cogw parameter file; ignored", l->name, path);
		return;
	}
	cogw_log(skipped ? COGW_LOG_WARNING : COGW_LOG_INFO, "line %s: loaded %u saved values from %s%s",
		 l->name, applied, path,
		 skipped ? " (some records did not match the dictionary and were skipped)" : "");
}

int line_store_load(line *l)
{
	/* The configured values, before any saved file changes them: what a
	 * later 1011h "load" makes the defaults again. Without memory for it
	 * "load" only takes effect at the next start (logged). */
	long n = write_parts(l->p.node.od, CO_OD_IMAGE_COMM | CO_OD_IMAGE_APP, l->store.blob,
			     LINE_STORE_MAX);
	if (n > 0 && (l->store.factory = malloc((size_t)n)) != NULL) {
		memcpy(l->store.factory, l->store.blob, (size_t)n);
		l->store.factory_len = (uint32_t)n;
	} else {
		cogw_log(COGW_LOG_WARNING, "line %s: cannot keep the configured values; 1011h \"load\" "
			 "takes effect at the next start only", l->name);
	}
	load_part(l, CO_OD_IMAGE_COMM);
	load_part(l, CO_OD_IMAGE_APP);
	return 0;
}
