/* SPDX-License-Identifier: MIT */
/*
 * lines/line_pending: the table of mailbox requests waiting for the core.
 * Slots of two kinds, O(1) take/find/release, the tag names the slot and
 * its generation (a late completion for a reused slot never matches), the
 * reply address and the buffers are the slot's.
 */
#include <errno.h>
#include <string.h>

#include "unity.h"

#include "lines/line_pending.h"

static line_pending_table t;

void setUp(void)
{
	TEST_ASSERT_EQUAL(0, line_pending_init(&t, 4096, NULL));
}

void tearDown(void)
{
	line_pending_fini(&t);
}

static mbx_request req_from(uint32_t client, uint64_t corr)
{
	mbx_request r;
	memset(&r, 0, sizeof r);
	r.code = MBX_CMD_SDO_UPLOAD;
	r.access = MBX_ACCESS_WRITE;
	r.reply.client = client;
	r.reply.corr = corr;
	return r;
}

static void test_take_find_release(void)
{
	mbx_request r = req_from(7, 99);
	line_pending *p = line_pending_take(&t, &r, LINE_PENDING_SDO, false);
	TEST_ASSERT_NOT_NULL(p);
	TEST_ASSERT_TRUE(p->used);
	TEST_ASSERT_EQUAL_UINT8(LINE_PENDING_SDO, p->kind);
	TEST_ASSERT_EQUAL_UINT32(7, p->reply.client);
	TEST_ASSERT_EQUAL_UINT64(99, p->reply.corr);
	TEST_ASSERT_EQUAL_UINT16(MBX_CMD_SDO_UPLOAD, p->code);
	TEST_ASSERT_EQUAL_PTR(p->inline_data, p->buf);
	TEST_ASSERT_EQUAL_UINT32(LINE_INLINE_MAX, p->cap);
	TEST_ASSERT_EQUAL_PTR(p, line_pending_find(&t, p->tag));
	TEST_ASSERT_EQUAL_UINT(1, t.used);
	uint64_t tag = p->tag;
	line_pending_release(&t, p);
	TEST_ASSERT_NULL(line_pending_find(&t, tag));
	TEST_ASSERT_EQUAL_UINT(0, t.used);
	line_pending_release(&t, p); /* twice: harmless */
	TEST_ASSERT_EQUAL_UINT(0, t.used);
}

static void test_reused_slot_gets_a_new_tag(void)
{
	mbx_request r = req_from(1, 1);
	line_pending *p = line_pending_take(&t, &r, LINE_PENDING_SDO, false);
	uint64_t old = p->tag;
	line_pending_release(&t, p);
	line_pending *q = line_pending_take(&t, &r, LINE_PENDING_LSS, false);
	TEST_ASSERT_EQUAL_PTR(p, q);                  /* same slot (top of the stack) ... */
	TEST_ASSERT_TRUE(q->tag != old);              /* ... another generation */
	TEST_ASSERT_NULL(line_pending_find(&t, old)); /* a late completion misses */
	TEST_ASSERT_EQUAL_PTR(q, line_pending_find(&t, q->tag));
	TEST_ASSERT_NULL(line_pending_find(&t, 0xFFFF)); /* slot out of range */
}

static void test_kinds_and_exhaustion(void)
{
	mbx_request r = req_from(1, 1);
	line_pending *big[LINE_BIG_SLOTS];
	for (int i = 0; i < LINE_BIG_SLOTS; i++) {
		big[i] = line_pending_take(&t, &r, LINE_PENDING_SDO, true);
		TEST_ASSERT_NOT_NULL(big[i]);
		TEST_ASSERT_EQUAL_UINT32(4096, big[i]->cap);
		TEST_ASSERT_TRUE(big[i]->buf != big[i]->inline_data);
	}
	TEST_ASSERT_NULL(line_pending_take(&t, &r, LINE_PENDING_SDO, true));
	for (int i = 0; i < LINE_PENDING_MAX - LINE_BIG_SLOTS; i++)
		TEST_ASSERT_NOT_NULL(line_pending_take(&t, &r, LINE_PENDING_SDO, false));
	TEST_ASSERT_NULL(line_pending_take(&t, &r, LINE_PENDING_SDO, false));
	TEST_ASSERT_EQUAL_UINT(LINE_PENDING_MAX, t.used);
	/* all tags distinct and each finds its slot */
	for (unsigned i = 0; i < LINE_PENDING_MAX; i++) {
		line_pending *p = line_pending_at(&t, i);
		TEST_ASSERT_EQUAL_PTR(p, line_pending_find(&t, p->tag));
	}
	line_pending_release(&t, big[2]);
	TEST_ASSERT_EQUAL_PTR(big[2], line_pending_take(&t, &r, LINE_PENDING_SDO, true));
}

static void test_last_slot_of_each_kind_is_for_writers(void)
{
	mbx_request w = req_from(1, 1), rd = req_from(2, 2);
	rd.access = MBX_ACCESS_READ;
	for (int i = 0; i < LINE_BIG_SLOTS - 1; i++)
		TEST_ASSERT_NOT_NULL(line_pending_take(&t, &rd, LINE_PENDING_SDO, true));
	TEST_ASSERT_NULL(line_pending_take(&t, &rd, LINE_PENDING_SDO, true));
	TEST_ASSERT_NOT_NULL(line_pending_take(&t, &w, LINE_PENDING_SDO, true));
	TEST_ASSERT_NULL(line_pending_take(&t, &w, LINE_PENDING_SDO, true));
	/* the small kind keeps its own writer slot */
	TEST_ASSERT_NOT_NULL(line_pending_take(&t, &rd, LINE_PENDING_SDO, false));
}

/* Big uploads are paid from the transfer memory budget as their data
 * arrives (docs/config.md transfer_memory): an announced size at once, otherwise in
 * MBX_BUFFER_KEEP steps; a read-only requester leaves cap to writers; the
 * release gives everything back. */
static void test_big_upload_pays_the_budget_as_it_grows(void)
{
	static line_pending_table b;
	mbx_budget budget;
	const uint32_t cap = 4 * MBX_BUFFER_KEEP;

	mbx_budget_init(&budget, 6 * MBX_BUFFER_KEEP);
	TEST_ASSERT_EQUAL(0, line_pending_init(&b, cap, &budget));
	mbx_request w = req_from(1, 1), r = req_from(2, 2);
	r.access = MBX_ACCESS_READ;
	line_pending *pw = line_pending_take(&b, &w, LINE_PENDING_SDO, true);
	line_pending *pr = line_pending_take(&b, &r, LINE_PENDING_SDO, true);
	TEST_ASSERT_NOT_NULL(pw);
	TEST_ASSERT_NOT_NULL(pr);
	/* size unknown: one step at a time */
	TEST_ASSERT_EQUAL_INT(0, line_pending_grow(pw, 100, UINT32_MAX));
	TEST_ASSERT_EQUAL_UINT64(MBX_BUFFER_KEEP, mbx_budget_used(&budget));
	TEST_ASSERT_EQUAL_INT(0, line_pending_grow(pw, MBX_BUFFER_KEEP + 1, UINT32_MAX));
	TEST_ASSERT_EQUAL_UINT64(2 * MBX_BUFFER_KEEP, mbx_budget_used(&budget));
	/* announced: all of it at once when it outgrows what it has; beyond
	 * cap: refused */
	TEST_ASSERT_EQUAL_INT(0, line_pending_grow(pw, 2 * MBX_BUFFER_KEEP + 1, cap));
	TEST_ASSERT_EQUAL_UINT64(cap, mbx_budget_used(&budget));
	TEST_ASSERT_EQUAL_INT(-ENOMEM, line_pending_grow(pw, cap + 1, UINT32_MAX));
	/* the reader may only use what leaves cap free: 6 - 4 - 4 < 0 */
	TEST_ASSERT_EQUAL_INT(-ENOMEM, line_pending_grow(pr, MBX_BUFFER_KEEP + 1, cap));
	TEST_ASSERT_TRUE(pr->over_budget);
	TEST_ASSERT_EQUAL_UINT64(1, atomic_load(&budget.refused));
	line_pending_release(&b, pw);
	TEST_ASSERT_EQUAL_UINT64(0, mbx_budget_used(&budget));
	/* now it fits (6 - 2 >= 4 left for writers) */
	TEST_ASSERT_EQUAL_INT(0, line_pending_grow(pr, 2 * MBX_BUFFER_KEEP, UINT32_MAX));
	line_pending_pay_back(pr);
	TEST_ASSERT_EQUAL_UINT64(0, mbx_budget_used(&budget));
	line_pending_release(&b, pr);
	TEST_ASSERT_EQUAL_UINT64(0, mbx_budget_used(&budget));
	line_pending_fini(&b);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_take_find_release);
	RUN_TEST(test_big_upload_pays_the_budget_as_it_grows);
	RUN_TEST(test_reused_slot_gets_a_new_tag);
	RUN_TEST(test_kinds_and_exhaustion);
	RUN_TEST(test_last_slot_of_each_kind_is_for_writers);
	return UNITY_END();
}
