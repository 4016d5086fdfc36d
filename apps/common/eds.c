/* SPDX-License-Identifier: MIT */
/*
 * apps/common/eds.c - CiA 306 EDS/DCF reader and its conversion to a
 * concise DCF (the contract is in eds.h).
 *
 * Three passes: (1) INI text to sections and keys, every line numbered;
 * (2) sections sorted so duplicates sit side by side and every lookup is
 * a binary search (a device file has ~1000 sections; the fuzzer feeds
 * many more); (3) objects walked in index order, every value parsed and
 * checked against its data type and limits - also values that will not
 * be written, because a file with a broken value is a broken file - and
 * the writable ones collected, then emitted in the order a slave accepts
 * them (PDO parameters in the CiA 301 re-mapping order).
 *
 * The passes in their own files, calling down only (eds_read.h):
 *
 *   eds.c          the conversion's entry points, the passes in order
 *   eds_emit.c     download order, the concise DCF written
 *   eds_objects.c  pass 3: objects, object links, object lists
 *   eds_value.c    one value: type, access, encoding, limits
 *   eds_num.c      integers, $NODEID, reals
 *   eds_ini.c      passes 1 and 2: INI text, sorted sections
 *   eds_base.c     messages, growing arrays, text
 */
#include "apps/common/eds.h"

#include <errno.h>
#include <fcntl.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "apps/common/file_read.h"
#include "apps/common/json_od.h"
#include "core/cdcf.h"
#include "core/od.h"
#include "apps/common/eds_read.h"

static void ctx_free(eds_ctx *c)
{
	for (size_t i = 0; i < c->nsecs; i++)
		free(c->secs[i].keys);
	for (size_t i = 0; i < c->nvars; i++)
		free(c->vars[i].data);
	free(c->secs);
	free(c->sorted);
	free(c->vars);
	free(c->emit);
	free(c->text);
}

/* Pass 3: the object lists, then every object and its links, in index
 * order. */
static int read_objects(eds_ctx *c)
{
	int rc;

	if ((rc = eds_do_list(c, "MandatoryObjects")) || (rc = eds_do_list(c, "OptionalObjects")) ||
	    (rc = eds_do_list(c, "ManufacturerObjects")) || (rc = eds_check_orphans(c)))
		return rc;
	for (size_t i = 0; i < c->nsecs && !rc; i++) {
		if (c->sorted[i]->kind == SEC_OBJ)
			rc = eds_do_object(c, c->sorted[i]);
		else if (c->sorted[i]->kind == SEC_LINKS)
			rc = eds_do_links(c, c->sorted[i]);
	}
	if (!rc && !c->st.objects)
		rc = eds_fail(c, 0, "no object sections: not an EDS or DCF");
	return rc;
}

static int convert(eds_ctx *c, const char *text, size_t len, uint8_t **out, size_t *out_len)
{
	int rc;

	if (c->node_id > 127)
		return eds_fail(c, 0, "node id %u is out of range 1..127", c->node_id);
	if (len > EDS_FILE_MAX)
		return eds_fail(c, 0, "file larger than %u bytes", EDS_FILE_MAX);
	c->text = malloc(len + 1);
	if (!c->text)
		return -ENOMEM;
	memcpy(c->text, text, len);
	c->text[len] = '\0';

	if ((rc = eds_parse_ini(c, len)) || (rc = eds_sort_sections(c)))
		return rc;
	if (!c->node_id && (rc = eds_node_from_file(c)))
		return rc;
	if ((rc = read_objects(c)) || (rc = eds_order_vars(c)) ||
	    (rc = eds_write_cdcf(c, out, out_len)))
		return rc;
	c->st.node_id = c->node_id;
	return 0;
}

int eds_convert_opts(const char *text, size_t len, const char *file, const eds_options *opts,
		     eds_result *res)
{
	eds_ctx c = { .file = file ? file : "(buffer)",
		      .node_id = opts->node_id,
		      .strict = opts->strict,
		      .on_warning = opts->on_warning,
		      .warning_arg = opts->warning_arg,
		      .on_entry = opts->on_entry,
		      .entry_arg = opts->entry_arg };
	int rc;

	res->cdcf = NULL;
	res->len = 0;
	rc = convert(&c, text, len, &res->cdcf, &res->len);
	if (rc) {
		free(res->cdcf);
		res->cdcf = NULL;
		res->len = 0;
	}
	res->stats = c.st; /* warnings too when the file was refused */
	if (rc == -ENOMEM)
		snprintf(res->err, sizeof res->err, "%s: out of memory", c.file);
	else
		snprintf(res->err, sizeof res->err, "%s", rc ? c.msg : "");
	ctx_free(&c);
	return rc;
}

int eds_convert(const char *text, size_t len, const char *file, uint8_t node_id, eds_result *res)
{
	eds_options o = { .node_id = node_id };

	return eds_convert_opts(text, len, file, &o, res);
}

int eds_convert_file_opts(const char *path, const eds_options *opts, eds_result *res)
{
	uint8_t *buf;
	size_t len;
	int rc;

	*res = (eds_result){ 0 };
	if ((rc = cogw_file_read(path, EDS_FILE_MAX, &buf, &len, res->err, sizeof res->err)))
		return rc;
	rc = eds_convert_opts((const char *)buf, len, path, opts, res);
	free(buf);
	return rc;
}

int eds_convert_file(const char *path, uint8_t node_id, eds_result *res)
{
	eds_options o = { .node_id = node_id };

	return eds_convert_file_opts(path, &o, res);
}
