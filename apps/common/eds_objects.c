/* SPDX-License-Identifier: MIT */
/*
 * apps/common/eds_objects.c - pass 3 of the EDS/DCF reader: the objects walked
 * in index order (plain, compact, with sub-sections), their object links,
 * the object lists checked against the sections.
 */
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "apps/common/eds_read.h"
#include "apps/common/json_od.h"
#include "core/cdcf.h"

static const ini_key *value_key(const ini_sec *s)
{
	const ini_key *k = eds_get_key(s, "ParameterValue");
	if (!k || !*k->val)
		k = eds_get_key(s, "DefaultValue");
	return k && *k->val ? k : NULL;
}

static bool has_parameter_value(const ini_sec *s)
{
	const ini_key *k = s ? eds_get_key(s, "ParameterValue") : NULL;
	return k && *k->val;
}

/* An entry whose DataType or AccessType cannot be used (rc, reason in
 * c->msg): refused when it carries a configured value, else left out
 * with a warning - python-canopen, too, writes nothing of an entry of
 * an unknown type. */
static int tolerate_untyped(eds_ctx *c, bool configured, int rc)
{
	return configured ? rc : eds_tolerate_failure(c, rc, "the entry is not used");
}

/* A VAR-like section (an object of type VAR/DOMAIN, or a sub-object). */
static int do_plain(eds_ctx *c, const ini_sec *s, uint16_t index, uint8_t sub, bool is_domain)
{
	const ini_key *ak = eds_get_key(s, "AccessType");
	var_spec v = {
		.index = index, .sub = sub, .sec = s, .value = value_key(s), .where = s->name
	};
	co_type t = CO_T_DOMAIN;
	uint8_t access = 0;
	int rc = 0;

	if (!(is_domain && !eds_get_key(s, "DataType")))
		rc = eds_parse_type(c, s, &t);
	if (!rc && !ak)
		rc = eds_fail(c, s->line, "[%s]: AccessType missing", s->name);
	else if (!rc)
		rc = eds_parse_access(c, ak, &access);
	if (rc)
		return tolerate_untyped(c, has_parameter_value(s), rc);
	return eds_do_var(c, &v, t, access);
}

/* [XXXXObjectLinks] and the object lists: a count key, then 1..count.
 * Read leniently, a missing count and entries that do not fit it are
 * warnings (they only describe, nothing is lost). */
static int check_keyed_list(eds_ctx *c, const ini_sec *s, const char *count_key, uint64_t max,
			    const ini_key **count_k)
{
	const ini_key *k = eds_get_key(s, count_key);
	uint64_t count = 0;
	int rc;

	*count_k = k;
	if (!k)
		return eds_tolerate(c, s->line, "[%s]: %s missing", s->name, count_key);
	if ((rc = eds_parse_uint_key(c, k, max, &count)))
		return eds_tolerate_failure(c, rc, "the count is not checked");
	for (size_t i = 0; i < s->nkeys; i++) {
		const ini_key *e = &s->keys[i];
		char *end;
		unsigned long n;
		if (e == k)
			continue;
		errno = 0;
		n = strtoul(e->key, &end, 10);
		if (*end || end == e->key || errno || e->key[0] == '-' || e->key[0] == '+')
			rc = eds_tolerate(c, e->line, "[%s]: unexpected key '%s'", s->name, e->key);
		else if ((n < 1 || n > count) && count == s->nkeys - 1) /* else: the count */
			rc = eds_tolerate(c, e->line, "[%s]: entry %s beyond %s=%llu", s->name,
					  e->key, count_key, (unsigned long long)count);
		if (rc)
			return rc;
	}
	if (count != s->nkeys - 1)
		return eds_tolerate(c, k->line, "[%s]: %s=%llu but %zu entries", s->name, count_key,
				    (unsigned long long)count, s->nkeys - 1);
	return 0;
}

/* Each numbered entry of a list names an object (its index); one the
 * file does not describe is a warning. */
static int check_listed_objects(eds_ctx *c, const ini_sec *s, const ini_key *count_k)
{
	for (size_t i = 0; i < s->nkeys; i++) {
		const ini_key *k = &s->keys[i];
		uint64_t idx;
		char *end;
		int rc;
		if (k == count_k)
			continue;
		(void)strtoul(k->key, &end, 10);
		if (*end || end == k->key)
			continue; /* reported by check_keyed_list */
		if ((rc = eds_parse_uint_key(c, k, 0xFFFF, &idx))) {
			if ((rc = eds_tolerate_failure(c, rc, "the entry is ignored")))
				return rc;
			continue;
		}
		if (eds_find_sec(c, SEC_OBJ, (uint16_t)idx, 0, NULL))
			continue;
		if (s->kind == SEC_LINKS)
			rc = eds_tolerate(c, k->line, "[%s]: linked object 0x%04llX has no section",
					  s->name, (unsigned long long)idx);
		else
			rc = eds_tolerate(
				c, k->line, "[%s]: object 0x%04llX listed but no section [%04llX]",
				s->name, (unsigned long long)idx, (unsigned long long)idx);
		if (rc)
			return rc;
	}
	return 0;
}

/* One key e of a [XXXXName] or [XXXXValue] section: a sub-index 1..n. */
static int check_compact_key(eds_ctx *c, const ini_sec *s, const ini_key *e, uint64_t n,
			     bool values)
{
	char *end;
	unsigned long sub;

	errno = 0;
	sub = strtoul(e->key, &end, 10);
	if (*end || end == e->key || errno || e->key[0] == '-' || e->key[0] == '+')
		return eds_tolerate(c, e->line, "[%s]: unexpected key '%s'%s", s->name, e->key,
				    c->strict ? "" : " (ignored)");
	if (sub >= 1 && sub <= n)
		return 0;
	if (values)
		return eds_fail(c, e->line, "[%s]: sub-index %s beyond CompactSubObj=%llu", s->name,
				e->key, (unsigned long long)n);
	return eds_tolerate(c, e->line, "[%s]: sub-index %s beyond CompactSubObj=%llu%s", s->name,
			    e->key, (unsigned long long)n, c->strict ? "" : " (ignored)");
}

/* [XXXXName] and [XXXXValue] of a compact object: NrOfEntries=k, then k
 * keys "sub=..." with sub-indexes 1..n (decimal). Read leniently, a wrong
 * count and names that fit no sub-object are warnings; a configured value
 * for a sub-object the object does not have is refused. */
static int check_compact_list(eds_ctx *c, const ini_sec *s, uint64_t n, bool values)
{
	const ini_key *k = eds_get_key(s, "NrOfEntries");
	uint64_t cnt = 0;
	int rc;

	if (!k && (rc = eds_tolerate(c, s->line, "[%s]: NrOfEntries missing", s->name)))
		return rc;
	if (k && (rc = eds_parse_uint_key(c, k, 255, &cnt)) &&
	    (rc = eds_tolerate_failure(c, rc, "the count is not checked")))
		return rc;
	for (size_t i = 0; i < s->nkeys; i++)
		if (&s->keys[i] != k && (rc = check_compact_key(c, s, &s->keys[i], n, values)))
			return rc;
	if (k && cnt != s->nkeys - 1)
		return eds_tolerate(c, k->line, "[%s]: NrOfEntries=%llu but %zu entries", s->name,
				    (unsigned long long)cnt, s->nkeys - 1);
	return 0;
}

/* The value of sub-index `sub` in a [XXXXValue] section. */
static const ini_key *compact_value(const ini_sec *vals, unsigned sub)
{
	char key[8];
	if (!vals)
		return NULL;
	snprintf(key, sizeof(key), "%u", sub);
	const ini_key *k = eds_get_key(vals, key);
	return k && *k->val ? k : NULL;
}

/* CompactSubObj=n of o: the number of sub-objects (0: none, a warning). */
static int compact_count(eds_ctx *c, const ini_sec *o, const ini_key *ck, uint64_t *n)
{
	int rc;

	if ((rc = eds_parse_uint_key(c, ck, 255, n)))
		return rc;
	if (*n == 0 && c->strict)
		return eds_fail(c, ck->line, "CompactSubObj must be 1..254");
	if (*n == 0) {
		eds_warn(c, ck->line, "[%s]: CompactSubObj=0: no sub-objects", o->name);
		return 0;
	}
	/* python-canopen makes sub-objects 1..255 of it; sub-index FFh is
	 * the object's structure (CiA 301), not an element */
	if (*n == 255 &&
	    (rc = eds_tolerate(c, ck->line,
			       "[%s]: CompactSubObj=255, but sub-index FFh is reserved (CiA 301)%s",
			       o->name, c->strict ? "" : ": sub-objects 1..254 are used")))
		return rc;
	if (*n == 255)
		*n = 254;
	return 0;
}

static int do_compact(eds_ctx *c, const ini_sec *o, const ini_key *ck)
{
	const ini_sec *names = eds_find_sec(c, SEC_NAME, o->index, 0, NULL);
	const ini_sec *vals = eds_find_sec(c, SEC_VALUE, o->index, 0, NULL);
	const ini_key *ak = eds_get_key(o, "AccessType");
	uint64_t n;
	co_type t;
	uint8_t access = 0;
	int rc;

	if ((rc = compact_count(c, o, ck, &n)) || !n)
		return rc;
	rc = eds_parse_type(c, o, &t);
	if (!rc && !ak)
		rc = eds_fail(c, o->line, "[%s]: AccessType missing", o->name);
	else if (!rc)
		rc = eds_parse_access(c, ak, &access);
	if (rc)
		return tolerate_untyped(c, has_parameter_value(o) || (vals && vals->nkeys > 1), rc);
	if (eds_find_sec(c, SEC_SUB, o->index, 0, NULL) ||
	    eds_lower_bound(c, SEC_SUB, o->index) < eds_lower_bound(c, SEC_NAME, o->index))
		return eds_fail(c, o->line, "[%s]: CompactSubObj and sub-object sections together",
				o->name);
	if (names && (rc = check_compact_list(c, names, n, false)))
		return rc;
	if (vals && (rc = check_compact_list(c, vals, n, true)))
		return rc;
	/* sub0 = n, UNSIGNED8 read-only: nothing to write */
	for (unsigned s = 1; s <= n; s++) {
		var_spec v = { .index = o->index, .sub = (uint8_t)s, .sec = o, .where = o->name };
		v.value = compact_value(vals, s);
		if (!v.value)
			v.value = value_key(o);
		if ((rc = eds_do_var(c, &v, t, access)))
			return rc;
	}
	return 0;
}

static const char *object_type_name(uint64_t ot)
{
	return ot == CO_OBJ_VAR      ? "VAR"
	       : ot == CO_OBJ_DOMAIN ? "DOMAIN"
	       : ot == CO_OBJ_ARRAY  ? "ARRAY"
				     : "RECORD";
}

/* A VAR or DOMAIN object: sub-object sections, SubNumber and
 * CompactSubObj do not belong to it; python-canopen ignores them. */
static int do_var_object(eds_ctx *c, const ini_sec *o, uint64_t ot, const ini_key *sn,
			 const ini_key *ck)
{
	size_t first = eds_lower_bound(c, SEC_SUB, o->index),
	       last = eds_lower_bound(c, SEC_NAME, o->index);
	int rc;

	if (first < last &&
	    (rc = eds_tolerate(c, c->sorted[first]->line, "[%s]: sub-object of %s object [%s]%s",
			       c->sorted[first]->name, object_type_name(ot), o->name,
			       c->strict ? "" : " (ignored)")))
		return rc;
	if ((sn || ck) && (rc = eds_tolerate(c, (sn ? sn : ck)->line, "[%s]: %s on a %s object%s",
					     o->name, (sn ? sn : ck)->key, object_type_name(ot),
					     c->strict ? "" : " (ignored)")))
		return rc;
	return do_plain(c, o, o->index, 0, ot == CO_OBJ_DOMAIN);
}

/* ARRAY/RECORD with sub-object sections. SubNumber (CiA 306: the number
 * of sub-objects) that disagrees with the sections is a warning: the
 * sections present are what python-canopen and the CANopenNode editor
 * read, and so do we. */
static int do_sub_sections(eds_ctx *c, const ini_sec *o, uint64_t ot, const ini_key *sn,
			   size_t first, size_t last)
{
	uint64_t n = 0;
	int rc;

	if (!sn && (rc = eds_tolerate(c, o->line, "[%s]: %s without SubNumber or CompactSubObj",
				      o->name, object_type_name(ot))))
		return rc;
	if (sn && (rc = eds_parse_uint_key(c, sn, 255, &n)) &&
	    (rc = eds_tolerate_failure(c, rc, "the sub-object sections present are used")))
		return rc;
	if (sn && !rc && n == 0 &&
	    (rc = eds_tolerate(c, sn->line, "[%s]: SubNumber 0 (an %s has at least sub-index 0)",
			       o->name, object_type_name(ot))))
		return rc;
	if (sn && n && last - first != n &&
	    (rc = eds_tolerate(c, sn->line,
			       "[%s]: SubNumber=%llu but %zu sub-object sections [%04XsubN]%s",
			       o->name, (unsigned long long)n, last - first, o->index,
			       c->strict ? "" : ": the sections present are used")))
		return rc;
	if (first < last && c->sorted[first]->sub != 0 &&
	    (rc = eds_tolerate(c, o->line, "[%s]: no sub-object section [%04Xsub0]", o->name,
			       o->index)))
		return rc;
	for (size_t i = first; i < last; i++) {
		const ini_sec *s = c->sorted[i];
		const ini_key *sot = eds_get_key(s, "ObjectType");
		uint64_t so = CO_OBJ_VAR;
		if (sot && *sot->val && (rc = eds_parse_uint_key(c, sot, 0xFF, &so)) &&
		    (rc = eds_tolerate_failure(c, rc, "taken as 0x7 (VAR)")))
			return rc;
		if (so != CO_OBJ_VAR &&
		    (rc = eds_tolerate(c, sot->line,
				       "[%s]: a sub-object must have ObjectType 0x7 (VAR)%s",
				       s->name, c->strict ? "" : "; taken as VAR")))
			return rc;
		if ((rc = do_plain(c, s, s->index, s->sub, false)))
			return rc;
	}
	return 0;
}

/* An ARRAY or RECORD: compact (CompactSubObj, ARRAY only) or with its
 * sub-sections. */
static int do_compound(eds_ctx *c, const ini_sec *o, uint64_t ot, const ini_key *sn,
		       const ini_key *ck)
{
	size_t first = eds_lower_bound(c, SEC_SUB, o->index),
	       last = eds_lower_bound(c, SEC_NAME, o->index);
	int rc;

	if (ck && ot != CO_OBJ_ARRAY && eds_find_sec(c, SEC_VALUE, o->index, 0, NULL))
		return eds_fail(c, ck->line, "[%s]: CompactSubObj on a RECORD (only ARRAY)",
				o->name);
	if (ck && ot != CO_OBJ_ARRAY &&
	    (rc = eds_tolerate(c, ck->line, "[%s]: CompactSubObj on a RECORD (only ARRAY)%s",
			       o->name, c->strict ? "" : ": the sub-object sections are used")))
		return rc;
	if (ck && ot == CO_OBJ_ARRAY) {
		if (sn) {
			uint64_t n;
			if ((rc = eds_parse_uint_key(c, sn, 255, &n)))
				return rc;
			if (n != 0)
				return eds_fail(c, sn->line,
						"[%s]: SubNumber and CompactSubObj together",
						o->name);
		}
		return do_compact(c, o, ck);
	}
	return do_sub_sections(c, o, ot, sn, first, last);
}

int eds_do_object(eds_ctx *c, const ini_sec *o)
{
	const ini_key *otk = eds_get_key(o, "ObjectType");
	const ini_key *sn = eds_get_key(o, "SubNumber"), *ck = eds_get_key(o, "CompactSubObj");
	uint64_t ot = CO_OBJ_VAR;
	int rc;

	c->st.objects++;
	if (o->index == 0)
		return eds_fail(c, o->line, "[%s]: index 0000h is not an object", o->name);
	if (otk && !*otk->val && !c->strict)
		otk = NULL; /* CiA 306: no ObjectType is VAR */
	if (otk && (rc = eds_parse_uint_key(c, otk, 0xFF, &ot)))
		return rc;
	if (ck && !*ck->val)
		ck = NULL;
	if (sn && !*sn->val && !c->strict)
		sn = NULL;
	switch (ot) {
	case CO_OBJ_DEFTYPE:
	case CO_OBJ_DEFSTRUCT:
		return 0; /* type definitions: nothing to configure */
	case CO_OBJ_VAR:
	case CO_OBJ_DOMAIN:
		return do_var_object(c, o, ot, sn, ck);
	case CO_OBJ_ARRAY:
	case CO_OBJ_RECORD:
		break;
	default: /* python-canopen skips such an object, and so do we */
		return eds_tolerate(
			c, otk->line,
			"ObjectType '%s' is not one of 0x2 (DOMAIN), 0x5 (DEFTYPE), 0x6 "
			"(DEFSTRUCT), 0x7 (VAR), 0x8 (ARRAY), 0x9 (RECORD)%s",
			otk->val, c->strict ? "" : ": the object is not used");
	}
	return do_compound(c, o, ot, sn, ck);
}

/* [XXXXObjectLinks]: ObjectLinks=n, 1..n = indexes of described objects. */
int eds_do_links(eds_ctx *c, const ini_sec *s)
{
	const ini_key *count_k;
	int rc;

	if (!eds_find_sec(c, SEC_OBJ, s->index, 0, NULL))
		return 0; /* reported by check_orphans */
	if ((rc = check_keyed_list(c, s, "ObjectLinks", 0xFFFF, &count_k)))
		return rc;
	return check_listed_objects(c, s, count_k);
}

/* Strict reading refuses a malformed object list (no count, an entry
 * that is no index). */
static int check_list_strictly(eds_ctx *c, const ini_sec *s)
{
	const ini_key *sk = eds_get_key(s, "SupportedObjects");
	uint64_t n;
	int rc;

	if (!sk)
		return eds_fail(c, s->line, "[%s]: SupportedObjects missing", s->name);
	if ((rc = eds_parse_uint_key(c, sk, 0xFFFF, &n)))
		return rc;
	for (size_t i = 0; i < s->nkeys; i++) {
		const ini_key *k = &s->keys[i];
		char *end;
		if (k == sk)
			continue;
		errno = 0;
		(void)strtoul(k->key, &end, 10);
		if (*end || end == k->key || errno || k->key[0] == '-' || k->key[0] == '+')
			return eds_fail(c, k->line, "[%s]: unexpected key '%s'", s->name, k->key);
		if ((rc = eds_parse_uint_key(c, k, 0xFFFF, &n)))
			return rc;
	}
	return 0;
}

/* [MandatoryObjects] etc.: SupportedObjects=n, 1..n = indexes. Vendor
 * files get the count wrong and list objects they do not describe;
 * nothing is lost, so these are warnings also when reading strictly. */
int eds_do_list(eds_ctx *c, const char *name)
{
	const ini_sec *s = eds_find_sec(c, SEC_OTHER, 0, 0, name);
	const ini_key *count_k;
	bool strict = c->strict;
	int rc;

	if (!s)
		return 0;
	if (strict && (rc = check_list_strictly(c, s)))
		return rc;
	c->strict = false;
	rc = check_keyed_list(c, s, "SupportedObjects", 0xFFFF, &count_k);
	if (!rc)
		rc = check_listed_objects(c, s, count_k);
	c->strict = strict;
	return rc;
}

int eds_check_orphans(eds_ctx *c)
{
	for (size_t i = 0; i < c->nsecs; i++) {
		const ini_sec *s = c->sorted[i];
		const ini_sec *o;
		if (s->kind == SEC_OTHER || s->kind == SEC_OBJ)
			continue;
		int rc = 0;
		o = eds_find_sec(c, SEC_OBJ, s->index, 0, NULL);
		/* a sub-object without its object has no object type, and
		 * configured values without their object have no type: both
		 * unusable (python-canopen refuses the first too) */
		if (!o && (s->kind == SEC_SUB || s->kind == SEC_VALUE))
			return eds_fail(c, s->line, "[%s] without object [%04X]", s->name,
					s->index);
		if (!o)
			rc = eds_tolerate(c, s->line, "[%s] without object [%04X]%s", s->name,
					  s->index, c->strict ? "" : " (ignored)");
		else if (s->kind == SEC_VALUE && !eds_get_key(o, "CompactSubObj"))
			return eds_fail(c, s->line, "[%s] but [%s] has no CompactSubObj", s->name,
					o->name);
		else if (s->kind == SEC_NAME && !eds_get_key(o, "CompactSubObj"))
			rc = eds_tolerate(c, s->line, "[%s] but [%s] has no CompactSubObj%s",
					  s->name, o->name, c->strict ? "" : " (ignored)");
		if (rc)
			return rc;
	}
	return 0;
}

int eds_node_from_file(eds_ctx *c)
{
	const ini_sec *s = eds_find_sec(c, SEC_OTHER, 0, 0, "DeviceComissioning");
	const ini_key *k = s ? eds_get_key(s, "NodeID") : NULL;
	uint64_t id;
	int rc;

	if (!k || !*k->val)
		return 0;
	/* EDS files carry NodeID=0 for "not commissioned": read leniently,
	 * a NodeID that is no node id is not used */
	if ((rc = eds_parse_uint_key(c, k, 127, &id)))
		return eds_tolerate_failure(c, rc, "NodeID is not used");
	if (id < 1)
		return eds_tolerate(c, k->line, "NodeID must be 1..127%s",
				    c->strict ? "" : ": NodeID is not used");
	c->node_id = (uint8_t)id;
	return 0;
}
