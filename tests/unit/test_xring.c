/* SPDX-License-Identifier: MIT */
/*
 * lines/xring: the cross-line hand-off ring. Order and content, the bound
 * (a full ring refuses and counts, never blocks), a closed ring refuses,
 * wrap-around of the counters, the wake-up only on empty -> non-empty, bad
 * arguments, the mesh of one ring per ordered pair. The multi-threaded
 * stress test runs under ThreadSanitizer (tests/tsan/).
 */
#include <errno.h>
#include <stdint.h>
#include <string.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include "unity.h"

#include "lines/xring.h"

static int efd;
static xring *r;

void setUp(void)
{
	efd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
	TEST_ASSERT_TRUE(efd >= 0);
	TEST_ASSERT_EQUAL(0, xring_create(&r, 4, 16, efd));
}

void tearDown(void)
{
	xring_destroy(r);
	close(efd);
}

/* Wake-ups pending on the eventfd (reads and resets the counter). */
static uint64_t wakes(void)
{
	eventfd_t v = 0;

	if (eventfd_read(efd, &v) < 0)
		return 0;
	return v;
}

static void test_fifo_order_and_content(void)
{
	uint8_t buf[16];

	TEST_ASSERT_EQUAL(0, xring_push(r, "one", 3));
	TEST_ASSERT_EQUAL(0, xring_push(r, "second", 6));
	TEST_ASSERT_EQUAL(2, xring_count(r));
	TEST_ASSERT_EQUAL(3, xring_pop(r, buf, sizeof buf));
	TEST_ASSERT_EQUAL_MEMORY("one", buf, 3);
	TEST_ASSERT_EQUAL(6, xring_pop(r, buf, sizeof buf));
	TEST_ASSERT_EQUAL_MEMORY("second", buf, 6);
	TEST_ASSERT_EQUAL(0, xring_pop(r, buf, sizeof buf));
}

static void test_full_ring_refuses_and_counts(void)
{
	uint8_t buf[16];
	xring_stats st;

	for (uint8_t i = 0; i < 4; i++)
		TEST_ASSERT_EQUAL(0, xring_push(r, &i, 1));
	uint8_t x = 99;
	TEST_ASSERT_EQUAL(-ENOBUFS, xring_push(r, &x, 1));
	TEST_ASSERT_EQUAL(-ENOBUFS, xring_push(r, &x, 1));
	xring_stats_get(r, &st);
	TEST_ASSERT_EQUAL_UINT64(4, st.pushed);
	TEST_ASSERT_EQUAL_UINT64(2, st.dropped);
	TEST_ASSERT_EQUAL_UINT32(4, st.high_water);
	/* Room again after one pop; what was queued is intact. */
	TEST_ASSERT_EQUAL(1, xring_pop(r, buf, sizeof buf));
	TEST_ASSERT_EQUAL_UINT8(0, buf[0]);
	TEST_ASSERT_EQUAL(0, xring_push(r, &x, 1));
	for (uint8_t want = 1; want < 4; want++) {
		TEST_ASSERT_EQUAL(1, xring_pop(r, buf, sizeof buf));
		TEST_ASSERT_EQUAL_UINT8(want, buf[0]);
	}
	TEST_ASSERT_EQUAL(1, xring_pop(r, buf, sizeof buf));
	TEST_ASSERT_EQUAL_UINT8(99, buf[0]);
	xring_stats_get(r, &st);
	TEST_ASSERT_EQUAL_UINT64(5, st.popped);
}

static void test_wake_only_when_it_was_empty(void)
{
	uint8_t buf[16];
	xring_stats st;

	TEST_ASSERT_EQUAL(0, xring_push(r, "a", 1));
	TEST_ASSERT_EQUAL_UINT64(1, wakes());
	TEST_ASSERT_EQUAL(0, xring_push(r, "b", 1)); /* consumer not done yet */
	TEST_ASSERT_EQUAL(0, xring_push(r, "c", 1));
	TEST_ASSERT_EQUAL_UINT64(0, wakes());
	while (xring_pop(r, buf, sizeof buf) > 0)
		;
	TEST_ASSERT_EQUAL(0, xring_push(r, "d", 1)); /* drained: wake again */
	TEST_ASSERT_EQUAL_UINT64(1, wakes());
	xring_stats_get(r, &st);
	TEST_ASSERT_EQUAL_UINT64(2, st.wakes);
}

/* A quiet push wakes nobody until wake_at messages are queued; the next
 * ordinary push wakes the consumer although the ring was not empty
 * (without that, the quiet messages and that one would wait for a
 * wake-up that nothing sends). */
static void test_quiet_push_and_the_wake_it_owes(void)
{
	char buf[8];

	TEST_ASSERT_EQUAL(0, xring_push_quiet(r, "q1", 2, 3));
	TEST_ASSERT_EQUAL(0, xring_push_quiet(r, "q2", 2, 3));
	TEST_ASSERT_EQUAL_UINT64(0, wakes());
	TEST_ASSERT_EQUAL(0, xring_push(r, "n", 1)); /* not empty, but owed */
	TEST_ASSERT_EQUAL_UINT64(1, wakes());
	TEST_ASSERT_EQUAL(0, xring_push(r, "m", 1)); /* nothing owed now */
	TEST_ASSERT_EQUAL_UINT64(0, wakes());
	while (xring_pop(r, buf, sizeof buf) > 0)
		;
	TEST_ASSERT_EQUAL(0, xring_push_quiet(r, "a", 1, 3));
	TEST_ASSERT_EQUAL(0, xring_push_quiet(r, "b", 1, 3));
	TEST_ASSERT_EQUAL_UINT64(0, wakes());
	TEST_ASSERT_EQUAL(0, xring_push_quiet(r, "c", 1, 3)); /* the third: wakes */
	TEST_ASSERT_EQUAL_UINT64(1, wakes());
	TEST_ASSERT_EQUAL(1, xring_pop(r, buf, sizeof buf)); /* in order */
	TEST_ASSERT_EQUAL_MEMORY("a", buf, 1);
	xring_stats st;
	xring_stats_get(r, &st);
	TEST_ASSERT_EQUAL_UINT64(7, st.pushed);
	TEST_ASSERT_EQUAL_UINT64(2, st.wakes);
}

/* A push whose wake-up comes later: the message is there at once, the
 * consumer's eventfd is written only by xring_wake, once; a wake with
 * nothing owed writes nothing. */
static void test_wake_later_push_wakes_at_xring_wake(void)
{
	char buf[8];

	TEST_ASSERT_EQUAL(0, xring_push_wake_later(r, "w", 1));
	TEST_ASSERT_EQUAL_UINT64(0, wakes());
	TEST_ASSERT_EQUAL_UINT(1, xring_count(r));
	xring_wake(r);
	TEST_ASSERT_EQUAL_UINT64(1, wakes());
	xring_wake(r);
	TEST_ASSERT_EQUAL_UINT64(0, wakes());
	TEST_ASSERT_EQUAL(1, xring_pop(r, buf, sizeof buf));
	TEST_ASSERT_EQUAL_MEMORY("w", buf, 1);
	/* owed and not woken: the next ordinary push pays it */
	TEST_ASSERT_EQUAL(0, xring_push_wake_later(r, "x", 1));
	TEST_ASSERT_EQUAL(0, xring_push(r, "y", 1));
	TEST_ASSERT_EQUAL_UINT64(1, wakes());
	TEST_ASSERT_EQUAL(1, xring_pop(r, buf, sizeof buf));
	TEST_ASSERT_EQUAL(1, xring_pop(r, buf, sizeof buf));
	/* a consumer that was awake and took it already: nothing to wake */
	TEST_ASSERT_EQUAL(0, xring_push_wake_later(r, "z", 1));
	TEST_ASSERT_EQUAL(1, xring_pop(r, buf, sizeof buf));
	xring_wake(r);
	TEST_ASSERT_EQUAL_UINT64(0, wakes());
}

static void test_closed_ring_refuses_but_drains(void)
{
	uint8_t buf[16];
	xring_stats st;

	TEST_ASSERT_EQUAL(0, xring_push(r, "a", 1));
	xring_close(r);
	TEST_ASSERT_TRUE(xring_is_closed(r));
	TEST_ASSERT_EQUAL(-EPIPE, xring_push(r, "b", 1));
	TEST_ASSERT_EQUAL(1, xring_pop(r, buf, sizeof buf));
	TEST_ASSERT_EQUAL(0, xring_pop(r, buf, sizeof buf));
	xring_stats_get(r, &st);
	TEST_ASSERT_EQUAL_UINT64(1, st.dropped);
}

static void test_counters_wrap_around(void)
{
	uint8_t buf[16];

	/* 70000 messages through 4 slots: the 16-bit range of slot indexes
	 * and any small-counter assumption are passed many times. */
	for (uint32_t i = 0; i < 70000; i++) {
		TEST_ASSERT_EQUAL(0, xring_push(r, &i, sizeof i));
		if (i % 3 == 2) {
			for (uint32_t k = 2; k <= 2; k--) {
				uint32_t got;
				TEST_ASSERT_EQUAL(4, xring_pop(r, &got, sizeof got));
				TEST_ASSERT_EQUAL_UINT32(i - k, got);
			}
		}
	}
	TEST_ASSERT_EQUAL(4, xring_pop(r, buf, sizeof buf));
	TEST_ASSERT_EQUAL(0, xring_count(r));
}

static void test_bad_arguments(void)
{
	xring *x;
	uint8_t big[17] = { 0 };
	uint8_t small[2];

	TEST_ASSERT_EQUAL(-EINVAL, xring_create(&x, 3, 16, -1)); /* not a power of two */
	TEST_ASSERT_EQUAL(-EINVAL, xring_create(&x, 1, 16, -1));
	TEST_ASSERT_EQUAL(-EINVAL, xring_create(&x, 131072, 16, -1));
	TEST_ASSERT_EQUAL(-EINVAL, xring_create(&x, 4, 0, -1));
	TEST_ASSERT_NULL(x);
	TEST_ASSERT_EQUAL(-EMSGSIZE, xring_push(r, big, sizeof big));
	TEST_ASSERT_EQUAL(-EMSGSIZE, xring_push(r, big, 0));
	TEST_ASSERT_EQUAL(0, xring_push(r, big, 16));
	TEST_ASSERT_EQUAL(-EMSGSIZE, xring_pop(r, small, sizeof small));
	TEST_ASSERT_EQUAL(1, xring_count(r)); /* nothing taken */
	xring_stats st;
	xring_stats_get(r, &st);
	TEST_ASSERT_EQUAL_UINT64(0, st.dropped); /* misuse is not a drop */
	/* Without a wake fd: works, never wakes. */
	TEST_ASSERT_EQUAL(0, xring_create(&x, 2, 4, -1));
	TEST_ASSERT_EQUAL(0, xring_push(x, "abc", 3));
	xring_stats_get(x, &st);
	TEST_ASSERT_EQUAL_UINT64(0, st.wakes);
	xring_destroy(x);
	xring_destroy(NULL);
}

static void test_mesh_one_ring_per_ordered_pair(void)
{
	xring_mesh *m;
	uint8_t buf[8];

	TEST_ASSERT_EQUAL(0, xring_mesh_create(&m, 3, NULL, 8, 8));
	TEST_ASSERT_EQUAL(3, xring_mesh_lines(m));
	TEST_ASSERT_NULL(xring_mesh_get(m, 1, 1));
	TEST_ASSERT_NULL(xring_mesh_get(m, 0, 3));
	TEST_ASSERT_NOT_NULL(xring_mesh_get(m, 0, 1));
	TEST_ASSERT_TRUE(xring_mesh_get(m, 0, 1) != xring_mesh_get(m, 1, 0));
	/* Both rings into line 2 wake line 2's fd; line 1's stays quiet. */
	TEST_ASSERT_EQUAL(0, xring_push(xring_mesh_get(m, 0, 2), "x", 1));
	TEST_ASSERT_EQUAL(0, xring_push(xring_mesh_get(m, 1, 2), "y", 1));
	eventfd_t v = 0;
	TEST_ASSERT_EQUAL(0, eventfd_read(xring_mesh_wake_fd(m, 2), &v));
	TEST_ASSERT_EQUAL_UINT64(2, v);
	TEST_ASSERT_EQUAL(-1, eventfd_read(xring_mesh_wake_fd(m, 1), &v));
	TEST_ASSERT_EQUAL(1, xring_pop(xring_mesh_get(m, 1, 2), buf, sizeof buf));
	TEST_ASSERT_EQUAL_UINT8('y', buf[0]);
	TEST_ASSERT_EQUAL(-1, xring_mesh_wake_fd(m, 3));
	xring_mesh_destroy(m);
	TEST_ASSERT_EQUAL(-EINVAL, xring_mesh_create(&m, 1, NULL, 8, 8));
	TEST_ASSERT_EQUAL(-EINVAL, xring_mesh_create(&m, 2, NULL, 6, 8));
	xring_mesh_destroy(NULL);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_fifo_order_and_content);
	RUN_TEST(test_full_ring_refuses_and_counts);
	RUN_TEST(test_wake_only_when_it_was_empty);
	RUN_TEST(test_quiet_push_and_the_wake_it_owes);
	RUN_TEST(test_wake_later_push_wakes_at_xring_wake);
	RUN_TEST(test_closed_ring_refuses_but_drains);
	RUN_TEST(test_counters_wrap_around);
	RUN_TEST(test_bad_arguments);
	RUN_TEST(test_mesh_one_ring_per_ordered_pair);
	return UNITY_END();
}
