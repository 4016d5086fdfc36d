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
 * the next start (or reset) brings the defaults back.
 *
 * File format (little-endian): "COGWOD1\n", then records
 * { u16 index, u8 sub, u32 len, len bytes }. On load every record is
 * checked against the OD (entry exists, length fits); bad ones are skipped
 * and counted in the log line, never trusted.
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/sdo_server.h"
#include "core/store.h"
#include "lines/log.h"

static const char file_magic[8] = { 'C', 'O', 'G', 'W', 'O', 'D', '1', '\n' };

/* A serialised store: two parts concatenated, lengths remembered. */
#define PART_COMM 0
#define PART_APP 1

static bool part_has(uint8_t sub, int part)
{
	return sub == 1 || (sub == 2 && part == PART_COMM) || (sub == 3 && part == PART_APP);
}

static bool entry_in_part(const co_od_entry *e, int part)
{
	if (e->index == CO_STORE_IDX_SAVE || e->index == CO_STORE_IDX_LOAD)
		return false;
	if (!(e->access & (CO_ACC_WRITE | CO_ACC_PERSIST)) || (e->access & CO_ACC_CONST))
		return false;
	bool comm = e->index >= 0x1000 && e->index <= 0x1FFF;
	return part == PART_COMM ? comm : e->index >= 0x2000;
}

/* Serialise one part into buf; returns bytes used or -EMSGSIZE. */
static long serialise(const co_od *od, int part, uint8_t *buf, size_t cap)
{
	size_t used = sizeof file_magic;
	if (cap < used)
		return -EMSGSIZE;
	memcpy(buf, file_magic, sizeof file_magic);
	for (size_t i = 0; i < co_od_count(od); i++) {
		const co_od_entry *e = co_od_at(od, i);
		if (!entry_in_part(e, part))
			continue;
		if (cap - used < 7u + e->size)
			return -EMSGSIZE;
		uint8_t *p = buf + used;
		co_put_le16(p, e->index);
		p[2] = e->sub;
		co_put_le32(p + 3, e->size);
		memcpy(p + 7, e->data, e->size);
		used += 7u + e->size;
	}
	return (long)used;
}

static void part_path(const line *l, int part, char *out, size_t len)
{
	snprintf(out, len, "%s.%s", l->state_path, part == PART_COMM ? "comm" : "app");
}

static uint32_t on_save(void *ctx, uint8_t sub, const co_od_access *a)
{
	line *l = ctx;
	if (sub > 3)
		return 0x08000020u; /* manufacturer parts: nothing defined */
	if (atomic_load(&l->store.state) != 0)
		return 0x08000022u; /* one save at a time: "device state" */
	l->store.op = 1;
	l->store.sub = sub;
	l->store.from_sdo = a->origin == CO_OD_ORIGIN_SDO;
	l->store.channel = a->channel;
	/* serialise now, on the line thread: the OD is only ever read here */
	uint32_t off = 0;
	for (int part = PART_COMM; part <= PART_APP; part++) {
		if (!part_has(sub, part))
			continue;
		long n = serialise(co_node_od(l->node), part, l->store.blob + off + 4,
				   LINE_STORE_MAX - off - 4);
		if (n < 0) {
			cogw_log(COGW_LOG_ERR, "line %s: save: values exceed %u bytes", l->name, LINE_STORE_MAX);
			return 0x08000020u;
		}
		co_put_le32(l->store.blob + off, (uint32_t)n);
		off += 4u + (uint32_t)n;
	}
	l->store.len = off;
	atomic_store(&l->store.state, 1);
	if (l->p.main_wakefd >= 0) {
		uint64_t one = 1;
		ssize_t w = write(l->p.main_wakefd, &one, sizeof one);
		(void)w;
	}
	return a->origin == CO_OD_ORIGIN_SDO ? CO_OD_DEFERRED : 0;
}

static uint32_t on_restore(void *ctx, uint8_t sub, const co_od_access *a)
{
	line *l = ctx;
	if (sub > 3)
		return 0x08000020u;
	if (atomic_load(&l->store.state) != 0)
		return 0x08000022u;
	l->store.op = 2;
	l->store.sub = sub;
	l->store.from_sdo = a->origin == CO_OD_ORIGIN_SDO;
	l->store.channel = a->channel;
	l->store.len = 0;
	atomic_store(&l->store.state, 1);
	if (l->p.main_wakefd >= 0) {
		uint64_t one = 1;
		ssize_t w = write(l->p.main_wakefd, &one, sizeof one);
		(void)w;
	}
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

static int write_atomically(const char *path, const uint8_t *data, size_t len)
{
	char tmp[420];
	snprintf(tmp, sizeof tmp, "%s.tmp", path);
	int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0640);
	if (fd < 0)
		return -errno;
	size_t done = 0;
	while (done < len) {
		ssize_t n = write(fd, data + done, len - done);
		if (n < 0) {
			if (errno == EINTR)
				continue;
			int e = -errno;
			close(fd);
			unlink(tmp);
			return e;
		}
		done += (size_t)n;
	}
	if (fsync(fd) != 0 || close(fd) != 0) {
		int e = -errno;
		unlink(tmp);
		return e;
	}
	if (rename(tmp, path) != 0) {
		int e = -errno;
		unlink(tmp);
		return e;
	}
	/* the rename itself must reach the disk too */
	char dir[420];
	snprintf(dir, sizeof dir, "%s", path);
	char *slash = strrchr(dir, '/');
	if (slash) {
		*slash = '\0';
		int dfd = open(*dir ? dir : "/", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
		if (dfd >= 0) {
			fsync(dfd);
			close(dfd);
		}
	}
	return 0;
}

bool line_store_service(line *l)
{
	if (!l || atomic_load(&l->store.state) != 1)
		return false;
	int rc = 0;
	char path[400];
	if (l->store.op == 1) {
		uint32_t off = 0;
		for (int part = PART_COMM; part <= PART_APP && !rc; part++) {
			if (!part_has(l->store.sub, part))
				continue;
			uint32_t n = co_get_le32(l->store.blob + off);
			part_path(l, part, path, sizeof path);
			rc = write_atomically(path, l->store.blob + off + 4, n);
			off += 4u + n;
		}
	} else {
		for (int part = PART_COMM; part <= PART_APP; part++) {
			if (!part_has(l->store.sub, part))
				continue;
			part_path(l, part, path, sizeof path);
			if (unlink(path) != 0 && errno != ENOENT)
				rc = -errno;
		}
	}
	if (rc)
		cogw_log(COGW_LOG_ERR, "line %s: %s %s: %s", l->name,
			 l->store.op == 1 ? "save to" : "restore (delete)", path, strerror(-rc));
	else
		cogw_log(COGW_LOG_INFO, "line %s: %s (1%s1h sub %u) done", l->name,
			 l->store.op == 1 ? "parameters saved" : "defaults restored for the next start",
			 l->store.op == 1 ? "01" : "01", l->store.sub);
	l->store.result = rc;
	atomic_store(&l->store.state, 2);
	uint64_t one = 1;
	ssize_t w = write(l->wakefd, &one, sizeof one);
	(void)w;
	return true;
}

/* ---- line thread ---------------------------------------------------------- */

void line_store_poll(line *l)
{
	if (atomic_load(&l->store.state) != 2)
		return;
	uint32_t abort = l->store.result ? 0x08000020u : 0;
	if (l->store.from_sdo)
		sdo_server_continue(l->node, l->store.channel, abort, NULL, 0, l->now_us);
	else
		mbx_server_respond(l->mbx, &l->store.reply, l->store.result ? MBX_E_INTERNAL : 0, 0, NULL, 0);
	atomic_store(&l->store.state, 0);
}

/* Start-up, before the node is created (its services read their objects
 * when they start) and before the thread runs, so plain file I/O is fine. */
static int load_part(line *l, int part)
{
	char path[400];
	part_path(l, part, path, sizeof path);
	FILE *f = fopen(path, "rb");
	if (!f)
		return errno == ENOENT ? 0 : -errno;
	long n = (long)fread(l->store.blob, 1, LINE_STORE_MAX, f);
	fclose(f);
	if (n < (long)sizeof file_magic || memcmp(l->store.blob, file_magic, sizeof file_magic)) {
		cogw_log(COGW_LOG_WARNING, "line %s: %s is not a cogw parameter file; ignored", l->name, path);
		return -EINVAL;
	}
	co_od *od = l->p.node.od;
	unsigned applied = 0, skipped = 0;
	long pos = sizeof file_magic;
	while (pos + 7 <= n) {
		const uint8_t *p = l->store.blob + pos;
		uint16_t index = co_get_le16(p);
		uint8_t sub = p[2];
		uint32_t len = co_get_le32(p + 3);
		if (len > (uint32_t)(n - pos - 7)) {
			skipped++;
			break; /* truncated file: stop, keep what was good */
		}
		co_od_entry *e = co_od_find(od, index, sub);
		if (e && entry_in_part(e, part) && co_od_check_value(e, p + 7, len) == 0 &&
		    co_od_entry_set_bytes(e, p + 7, len) == 0)
			applied++;
		else
			skipped++;
		pos += 7 + (long)len;
	}
	cogw_log(COGW_LOG_INFO, "line %s: loaded %u saved values from %s%s", l->name, applied, path,
		 skipped ? " (some records did not match the dictionary and were skipped)" : "");
	return 0;
}

int line_store_load(line *l)
{
	load_part(l, PART_COMM);
	load_part(l, PART_APP);
	return 0;
}
