/* SPDX-License-Identifier: MIT */
/*
 * Stress of the cross-line rings under ThreadSanitizer (build/tsan): one
 * thread per "line", a mesh of one small ring per ordered pair, every line
 * sending to every other one as fast as it can while draining its own
 * inbound rings the way a line thread does (sleep in poll on its eventfd,
 * pop until empty). Checked:
 * - no data race (TSan fails the run on one);
 * - per ring, messages arrive complete, in order, none twice: the payload
 *   carries (from, to, seq) and a pattern derived from them;
 * - nothing is lost silently: accepted = received, and every refusal the
 *   producer saw is a counted drop;
 * - no lost wake-up: a consumer that sleeps 2 s on its eventfd while one
 *   of its rings holds a message fails the test;
 * - a dead target (one line stops consuming and closes its rings) never
 *   blocks the others: their pushes fail fast (-EPIPE / -ENOBUFS) and are
 *   counted.
 */
#include <errno.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/eventfd.h>
#include <time.h>
#include <unistd.h>

#include "unity.h"

#include "lines/xring.h"

#define LINES 4
#define PER_PAIR 20000u /* messages each line sends to each other line */
#define MSG_MAX 48u

typedef struct msg {
	uint16_t from, to;
	uint32_t seq;
	uint8_t pattern[32];
} msg;

typedef struct line_sim {
	unsigned id;
	xring_mesh *mesh;
	bool dies;             /* stops consuming early and closes its rings */
	bool paced;            /* a refused message is sent again later */
	atomic_bool *all_sent; /* set when every producer is done */
	/* results, read by the main thread after join */
	uint64_t sent[LINES], refused_full[LINES], refused_closed[LINES];
	uint64_t received[LINES];
	uint32_t next_seq[LINES]; /* expected from each sender */
	unsigned bad, lost_wakes;
} line_sim;

static atomic_uint producers_left;

void setUp(void) {}

void tearDown(void) {}

static void fill(msg *m)
{
	for (unsigned i = 0; i < sizeof m->pattern; i++)
		m->pattern[i] = (uint8_t)(m->seq * 31u + m->from * 7u + m->to + i);
}

static bool intact(const msg *m)
{
	msg want = *m;
	fill(&want);
	return memcmp(want.pattern, m->pattern, sizeof m->pattern) == 0;
}

/* Pop every inbound ring until all are empty; false if this line must stop. */
static void drain(line_sim *s)
{
	bool any;
	do {
		any = false;
		for (unsigned from = 0; from < LINES; from++) {
			xring *r = xring_mesh_get(s->mesh, from, s->id);
			msg m;
			int n;
			if (!r)
				continue;
			while ((n = xring_pop(r, &m, sizeof m)) > 0) {
				any = true;
				if (n != (int)sizeof m || m.from != from || m.to != s->id ||
				    !intact(&m) || m.seq < s->next_seq[from]) {
					s->bad++;
					continue;
				}
				/* gaps are the refused messages: the sender never got
				 * them accepted, so they never come */
				s->next_seq[from] = m.seq + 1;
				s->received[from]++;
			}
		}
	} while (any);
}

static bool inbound_empty(line_sim *s)
{
	for (unsigned from = 0; from < LINES; from++) {
		xring *r = xring_mesh_get(s->mesh, from, s->id);
		if (r && xring_count(r))
			return false;
	}
	return true;
}

static void *line_main(void *arg)
{
	line_sim *s = arg;
	int wfd = xring_mesh_wake_fd(s->mesh, s->id);
	uint32_t seq[LINES] = { 0 };
	bool sending = true, dead = false;

	while (sending || !atomic_load(s->all_sent) || !inbound_empty(s)) {
		if (sending) {
			/* a burst to everybody, then look at the inbox */
			sending = false;
			for (unsigned to = 0; to < LINES; to++) {
				if (to == s->id || seq[to] >= PER_PAIR)
					continue;
				for (int k = 0; k < 8 && seq[to] < PER_PAIR; k++) {
					msg m = { .from = (uint16_t)s->id,
						  .to = (uint16_t)to,
						  .seq = seq[to]++ };
					fill(&m);
					int rc = xring_push(xring_mesh_get(s->mesh, s->id, to), &m,
							    sizeof m);
					if (rc == 0) {
						s->sent[to]++;
					} else if (rc == -ENOBUFS) {
						/* the target is behind: counted, move on
						 * (a line answers its requester with an
						 * error and never waits) */
						s->refused_full[to]++;
						if (s->paced)
							seq[to]--; /* again next round */
						break;
					} else if (rc == -EPIPE)
						s->refused_closed[to]++;
					else
						s->bad++;
				}
				if (seq[to] < PER_PAIR)
					sending = true;
			}
			if (!sending)
				atomic_fetch_sub(&producers_left, 1);
		}
		if (dead) {
			/* a dead line only keeps sending; at the end it takes
			 * what was accepted just before its close */
			if (atomic_load(s->all_sent))
				drain(s);
			else if (!sending)
				poll(NULL, 0, 1);
			continue;
		}
		if (s->dies && seq[(s->id + 1) % LINES] >= 16) {
			for (unsigned from = 0; from < LINES; from++)
				if (from != s->id)
					xring_close(xring_mesh_get(s->mesh, from, s->id));
			dead = true;
			drain(s); /* what was accepted before the close still counts */
			continue;
		}
		if (!sending) {
			/* Sleep like a line thread. Anything queued must wake us:
			 * a 2 s sleep with a message waiting is a lost wake-up. */
			struct pollfd p = { .fd = wfd, .events = POLLIN };
			int n = poll(&p, 1, atomic_load(s->all_sent) ? 50 : 2000);
			if (n == 0 && !atomic_load(s->all_sent) && !inbound_empty(s))
				s->lost_wakes++;
		}
		eventfd_t v;
		eventfd_read(wfd, &v); /* non-blocking: reset the counter */
		drain(s);
		if (atomic_load(&producers_left) == 0)
			atomic_store(s->all_sent, true);
	}
	return NULL;
}

static void run(bool with_dead_line, bool paced)
{
	xring_mesh *mesh;
	line_sim sim[LINES];
	pthread_t th[LINES];
	atomic_bool all_sent = false;

	TEST_ASSERT_EQUAL(0, xring_mesh_create(&mesh, LINES, NULL, 64, MSG_MAX));
	atomic_store(&producers_left, LINES);
	memset(sim, 0, sizeof sim);
	for (unsigned i = 0; i < LINES; i++) {
		sim[i].id = i;
		sim[i].mesh = mesh;
		sim[i].all_sent = &all_sent;
		sim[i].dies = with_dead_line && i == LINES - 1;
		sim[i].paced = paced;
	}
	for (unsigned i = 0; i < LINES; i++)
		TEST_ASSERT_EQUAL(0, pthread_create(&th[i], NULL, line_main, &sim[i]));
	for (unsigned i = 0; i < LINES; i++)
		pthread_join(th[i], NULL);

	uint64_t accepted = 0, refused = 0, dropped = 0;
	for (unsigned to = 0; to < LINES; to++) {
		TEST_ASSERT_EQUAL_UINT_MESSAGE(0, sim[to].bad,
					       "corrupt, reordered or duplicated message");
		TEST_ASSERT_EQUAL_UINT_MESSAGE(0, sim[to].lost_wakes, "lost wake-up");
		for (unsigned from = 0; from < LINES; from++) {
			xring *r = xring_mesh_get(mesh, from, to);
			xring_stats st;
			if (!r)
				continue;
			xring_stats_get(r, &st);
			const line_sim *p = &sim[from];
			/* every refusal the producer saw is a counted drop, and
			 * every accepted message arrived exactly once */
			TEST_ASSERT_EQUAL_UINT64(p->refused_full[to] + p->refused_closed[to],
						 st.dropped);
			TEST_ASSERT_EQUAL_UINT64(p->sent[to], st.pushed);
			TEST_ASSERT_EQUAL_UINT64(p->sent[to], sim[to].received[from]);
			if (paced)
				TEST_ASSERT_EQUAL_UINT64(PER_PAIR, p->sent[to]); /* all, in order */
			else
				TEST_ASSERT_EQUAL_UINT64(PER_PAIR, p->sent[to] +
									   p->refused_full[to] +
									   p->refused_closed[to]);
			accepted += p->sent[to];
			refused += p->refused_full[to] + p->refused_closed[to];
			dropped += st.dropped;
			if (with_dead_line && to == LINES - 1)
				TEST_ASSERT_TRUE(p->refused_closed[to] > 0);
			else
				TEST_ASSERT_EQUAL_UINT64(0, p->refused_closed[to]);
		}
	}
	TEST_ASSERT_EQUAL_UINT64(refused, dropped);
	TEST_ASSERT_TRUE(accepted > 0);
	char line[160];
	snprintf(line, sizeof line, "%s: %llu accepted and received, %llu refused and counted",
		 with_dead_line ? "with a dead line"
		 : paced        ? "paced senders"
				: "all alive",
		 (unsigned long long)accepted, (unsigned long long)refused);
	TEST_MESSAGE(line);
	xring_mesh_destroy(mesh);
}

static void test_all_lines_alive(void)
{
	run(false, false);
}

static void test_paced_senders_deliver_everything(void)
{
	run(false, true);
}

static void test_dead_line_never_blocks_the_others(void)
{
	run(true, false);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_all_lines_alive);
	RUN_TEST(test_paced_senders_deliver_everything);
	RUN_TEST(test_dead_line_never_blocks_the_others);
	return UNITY_END();
}
