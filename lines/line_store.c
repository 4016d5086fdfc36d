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
 * format) sealed with core/store_file.h: a CRC-32 over the image and a
 * generation shared by the files of one save. A file that fails the
 * check (truncated, a flipped bit, no seal), or a save cut between its two
 * files (the newest file names a part whose file has another
 * generation), is damaged: nothing at all is loaded, the line starts on
 * its configured values, logs an error and sends EMCY 6300h "data set"
 * (a kill between the two renames must not leave them inconsistent, a
 * bit flip must not load as another value, a truncated file must not
 * half-apply).
 * 1011h "load" first re-seals the parts that stay (so they no longer name
 * the deleted ones), then deletes. On load every record is checked
 * against the OD and bad ones are skipped and counted in the log line,
 * never trusted.
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <sys/eventfd.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/od_image.h"
#include "core/emcy.h"
#include "core/sdo.h"
#include "core/sdo_server.h"
#include "core/store.h"
#include "core/store_file.h"
#include "lines/file_atomic.h"
#include "lines/log.h"

/* Each part in its own file; the save buffer holds the parts one after the
 * other, each prefixed with its length. */
static const unsigned parts[] = { CO_OD_IMAGE_COMM, CO_OD_IMAGE_APP };
#define N_PARTS 2

/* 1010h/1011h sub-index -> the parts it covers (CiA 301 §7.5.2.13). */
static unsigned parts_of_sub(uint8_t sub)
{
	return sub == 2   ? CO_OD_IMAGE_COMM
	       : sub == 3 ? CO_OD_IMAGE_APP
			  : CO_OD_IMAGE_COMM | CO_OD_IMAGE_APP;
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
		return SDO_AB_STORE; /* manufacturer parts: nothing defined */
	if (atomic_load(&l->store.state) != 0)
		return SDO_AB_DEV_STATE; /* one save at a time: "device state" */
	/* serialise now, on the line thread: the OD is only ever read here */
	long n = write_parts(co_node_od(l->node), parts_of_sub(sub), l->store.blob, LINE_STORE_MAX);
	if (n < 0) {
		cogw_log(COGW_LOG_ERR, "line %s: save: values exceed %u bytes", l->name,
			 LINE_STORE_MAX);
		return SDO_AB_STORE;
	}
	l->store.len = (uint32_t)n;
	request_main(l, 1, sub, a);
	return a->origin == CO_OD_ORIGIN_SDO ? CO_OD_DEFERRED : 0;
}

static uint32_t on_restore(void *ctx, uint8_t sub, const co_od_access *a)
{
	line *l = ctx;
	if (sub > 3)
		return SDO_AB_STORE;
	if (atomic_load(&l->store.state) != 0)
		return SDO_AB_DEV_STATE;
	l->store.len = 0;
	request_main(l, 2, sub, a);
	return a->origin == CO_OD_ORIGIN_SDO ? CO_OD_DEFERRED : 0;
}

static const co_store_ops store_ops = { .save = on_save, .restore = on_restore };

int line_store_attach(line *l)
{
	int rc = co_store_attach(l->node, &store_ops, l, 3, CO_STORE_CAP_CMD, CO_STORE_CAP_CMD);
	if (rc < 0 && rc != -EEXIST)
		cogw_log(COGW_LOG_ERR, "line %s: cannot attach 1010h/1011h: %s", l->name,
			 strerror(-rc));
	return rc == -EEXIST ? 0 : rc;
}

/* Start a save (op 1) or restore (op 2) for a mailbox request; answered
 * by line_store_poll() when the main thread is done. */
static int store_request_mbx(line *l, uint8_t op, uint8_t sub, const mbx_reply_to *to)
{
	if (sub < 1 || sub > 3 || (op != 1 && op != 2))
		return -EINVAL;
	co_od_access a = { .origin = CO_OD_ORIGIN_LOCAL };
	uint32_t abort = op == 1 ? on_save(l, sub, &a) : on_restore(l, sub, &a);
	if (abort == SDO_AB_DEV_STATE)
		return -EBUSY;
	if (abort)
		return -EIO;
	l->store.reply = *to;
	return 0;
}

/* Mailbox STORE / RESTORE. */
void line_store_command(line *l, const mbx_request *req)
{
	mbx_store_req s;
	memcpy(&s, req->payload, sizeof s);
	if (!l->state_path[0])
		return line_answer(l, &req->reply, MBX_E_UNSUPPORTED, 0, NULL, 0);
	int rc = store_request_mbx(l, req->code == MBX_CMD_STORE ? 1 : 2, s.sub, &req->reply);
	if (rc < 0)
		line_answer(l, &req->reply, mbx_status_of_errno(rc), 0, NULL, 0);
}

/* ---- main thread ---------------------------------------------------------- */

/* Read a saved part file (at most cap bytes) into buf. Returns its length,
 * -ENOENT if there is none, -EFBIG if larger than cap, or -errno. Only a
 * regular file is read: O_NONBLOCK, so a FIFO put there cannot block. */
static long read_part(const char *path, uint8_t *buf, size_t cap)
{
	int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
	struct stat st;
	size_t n = 0;

	if (fd < 0)
		return -errno;
	if (fstat(fd, &st) < 0 || !S_ISREG(st.st_mode)) {
		close(fd);
		return -EINVAL;
	}
	while (n < cap) {
		ssize_t r = read(fd, buf + n, cap - n);

		if (r < 0 && errno == EINTR)
			continue;
		if (r < 0) {
			int e = errno;

			close(fd);
			return -e;
		}
		if (r == 0)
			break;
		n += (size_t)r;
	}
	if (n == cap) {
		uint8_t extra;

		if (read(fd, &extra, 1) > 0) {
			close(fd);
			return -EFBIG;
		}
	}
	close(fd);
	return (long)n;
}

/* The generation and set of a part file on disk (0 if none or damaged). */
static co_store_file_info part_info(const line *l, unsigned part, uint8_t *buf, size_t cap)
{
	char path[400];
	co_store_file_info info = { 0 };

	part_path(l, part, path, sizeof path);
	long n = read_part(path, buf, cap);
	if (n < 0 || co_store_file_check(buf, (size_t)n, &info) < 0)
		info = (co_store_file_info){ 0 };
	return info;
}

/* Write a part (image of n bytes) sealed with generation gen and set. */
static int write_part(const char *path, const uint8_t *image, uint32_t n, uint32_t gen,
		      uint32_t set)
{
	uint8_t *buf = malloc((size_t)n + CO_STORE_FILE_TRAILER);
	if (!buf)
		return -ENOMEM;
	memcpy(buf, image, n);
	long len = co_store_file_seal(buf, n, (size_t)n + CO_STORE_FILE_TRAILER, gen, set);
	int rc = len < 0 ? (int)len : file_write_atomic(path, buf, (size_t)len, 0640);
	free(buf);
	return rc;
}

/* 1011h: the parts that stay get a seal that no longer names the deleted
 * ones (else the set would read as torn), then the others are deleted. */
static int restore_parts(line *l, unsigned del, uint8_t *tmp, size_t cap)
{
	char path[400];
	int rc = 0;
	for (int i = 0; i < N_PARTS && !rc; i++) {
		if (del & parts[i])
			continue;
		part_path(l, parts[i], path, sizeof path);
		long n = read_part(path, tmp, cap);
		co_store_file_info info;
		if (n < 0 || co_store_file_check(tmp, (size_t)n, &info) < 0 || !(info.set & del))
			continue;
		rc = write_part(path, tmp, (uint32_t)info.image_len, info.generation,
				info.set & ~del);
	}
	for (int i = 0; i < N_PARTS && !rc; i++) {
		part_path(l, parts[i], path, sizeof path);
		if ((del & parts[i]) && unlink(path) != 0 && errno != ENOENT)
			rc = -errno;
	}
	return rc;
}

bool line_store_service(line *l)
{
	if (!l || atomic_load(&l->store.state) != 1)
		return false;
	int rc = 0;
	char path[400];
	uint32_t off = 0;
	unsigned set = parts_of_sub(l->store.sub);
	uint8_t *tmp = malloc(LINE_STORE_MAX); /* main thread: not real time */
	uint32_t gen = 0;
	if (!tmp)
		rc = -ENOMEM;
	/* one generation newer than anything on disk: see core/store_file.h */
	for (int i = 0; i < N_PARTS && !rc && l->store.op == 1; i++) {
		co_store_file_info info = part_info(l, parts[i], tmp, LINE_STORE_MAX);
		if (info.generation > gen)
			gen = info.generation;
	}
	gen++;
	if (!rc && l->store.op == 2) {
		rc = restore_parts(l, set, tmp, LINE_STORE_MAX);
		snprintf(path, sizeof path, "%s.*", l->state_path);
	}
	for (int i = 0; i < N_PARTS && !rc && l->store.op == 1; i++) {
		if (!(set & parts[i]))
			continue;
		part_path(l, parts[i], path, sizeof path);
		uint32_t n = co_get_le32(l->store.blob + off);
		rc = write_part(path, l->store.blob + off + 4, n, gen, set);
		off += 4u + n;
	}
	free(tmp);
	if (rc)
		cogw_log(COGW_LOG_ERR, "line %s: %s %s: %s", l->name,
			 l->store.op == 1 ? "save to" : "restore (delete)", path, strerror(-rc));
	else
		cogw_log(COGW_LOG_INFO, "line %s: %s (%s sub %u)", l->name,
			 l->store.op == 1 ? "parameters saved"
					  : "defaults restored for the next reset or start",
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
			co_od_image_apply(co_node_od(l->node), buf + off + 4, n,
					  CO_OD_IMAGE_SET_DEFAULT, &applied, &skipped);
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
	/* Whatever the file's errno (a full disk is no "busy"): CiA 301
	 * §7.5.2.13/14 answer a failed save/load with 08000020, the mailbox
	 * with INTERNAL (docs/mailbox.md). */
	uint32_t abort = l->store.result ? SDO_AB_STORE : 0;
	if (l->store.from_sdo)
		sdo_server_continue(l->node, l->store.channel, abort, NULL, 0, l->now_us);
	else
		mbx_server_respond(l->mbx, &l->store.reply, l->store.result ? MBX_E_INTERNAL : 0, 0,
				   NULL, 0);
	atomic_store(&l->store.state, 0);
}

/* The configured values, before any saved file changes them: what a
 * later 1011h "load" makes the defaults again. Without memory for it
 * "load" only takes effect at the next start (logged). */
static void keep_configured_values(line *l)
{
	long n = write_parts(l->p.node.od, CO_OD_IMAGE_COMM | CO_OD_IMAGE_APP, l->store.blob,
			     LINE_STORE_MAX);
	if (n > 0 && (l->store.factory = malloc((size_t)n)) != NULL) {
		memcpy(l->store.factory, l->store.blob, (size_t)n);
		l->store.factory_len = (uint32_t)n;
	} else {
		cogw_log(COGW_LOG_WARNING,
			 "line %s: cannot keep the configured values; 1011h \"load\" "
			 "takes effect at the next start only",
			 l->name);
	}
}

/* Start-up, before the node is created (its services read their objects
 * when they start) and before the thread runs, so plain file I/O is fine.
 * Both parts are read and checked first; only a whole, consistent set is
 * applied. */
int line_store_load(line *l)
{
	keep_configured_values(l);
	char path[N_PARTS][400];
	long len[N_PARTS];
	co_store_file_info info[N_PARTS] = { { 0 } };
	int present[N_PARTS] = { 0 };
	uint8_t *buf[N_PARTS] = { l->store.blob, malloc(LINE_STORE_MAX) };
	const char *damage = NULL;
	int bad = -1;

	if (!buf[1]) {
		cogw_log(COGW_LOG_ERR, "line %s: cannot load saved values: out of memory", l->name);
		return -ENOMEM;
	}
	for (int i = 0; i < N_PARTS && !damage; i++) {
		part_path(l, parts[i], path[i], sizeof path[i]);
		len[i] = read_part(path[i], buf[i], LINE_STORE_MAX);
		if (len[i] == -ENOENT)
			continue;
		bad = i;
		if (len[i] == -EINVAL)
			damage = "is not a regular file";
		else if (len[i] == -EFBIG)
			damage = "is too large";
		else if (len[i] < 0)
			damage = strerror((int)-len[i]);
		else if ((size_t)len[i] < CO_OD_IMAGE_MAGIC_LEN ||
			 memcmp(buf[i], "COGWOD1\n", CO_OD_IMAGE_MAGIC_LEN) != 0)
			damage = "is not a cogw parameter file; ignored,";
		else {
			int rc = co_store_file_check(buf[i], (size_t)len[i], &info[i]);
			if (rc == -ENODATA)
				damage = "has no checksum (truncated, or not written by cogw)";
			else if (rc < 0)
				damage = "fails its checksum (damaged)";
		}
		present[i] = 1;
	}
	if (!damage && co_store_file_torn(info, present, parts, N_PARTS)) {
		damage = "belongs to an interrupted save (its parts are of different generations)";
		bad = 0;
	}
	if (damage) {
		/* never half-apply: all configured values, an error, an EMCY */
		cogw_log(COGW_LOG_ERR,
			 "line %s: saved parameters damaged: %s %s; none of them loaded, starting "
			 "with "
			 "the configured values (EMCY 6300h)",
			 l->name, path[bad], damage);
		l->store.damaged = true;
		free(buf[1]);
		return 0;
	}
	for (int i = 0; i < N_PARTS; i++) {
		if (!present[i])
			continue;
		unsigned applied = 0, skipped = 0;
		co_od_image_apply(l->p.node.od, buf[i], info[i].image_len,
				  CO_OD_IMAGE_SET_VALUE | CO_OD_IMAGE_SET_DEFAULT, &applied,
				  &skipped);
		cogw_log(skipped ? COGW_LOG_WARNING : COGW_LOG_INFO,
			 "line %s: loaded %u saved values from %s%s", l->name, applied, path[i],
			 skipped ? " (some records did not match the dictionary and were skipped)"
				 : "");
	}
	free(buf[1]);
	return 0;
}

void line_store_started(line *l)
{
	static const uint8_t msef[5] = { 0 };

	if (l->store.damaged)
		co_emcy_send(l->node, 0x6300u /* data set (CiA 301 table 21) */,
			     CO_EMCY_REG_GENERIC, msef, l->now_us);
}
