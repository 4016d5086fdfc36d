/* lines/socketcan on real vcan lines: frames in and out with kernel timestamps,
 * malformed frames refused, transmit back-pressure with a bounded queue and
 * watermarks (no busy loop, nothing lost while the queue has room), receive
 * overflow counted through SO_RXQ_OVFL. */
#include <errno.h>
#include <stdlib.h>
#include <linux/can.h>
#include <net/if.h>
#include <poll.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "lines/socketcan.h"
#include "unity.h"

static can_port *a, *b;
static void unlimit_rate(const char *ifname);

static uint64_t now_us(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static can_port *open_port(const char *ifname, uint16_t txq)
{
	can_port_config cfg = { .ifname = ifname, .bitrate = 1000000, .tx_queue_len = txq };
	can_port *p = NULL;
	const char *why = NULL;
	int rc = can_port_open(&p, &cfg, &why);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, rc, why ? why : "can_port_open");
	return p;
}

void setUp(void)
{
	a = open_port("vcan0", 64);
	b = open_port("vcan0", 64);
}

void tearDown(void)
{
	can_port_close(a);
	can_port_close(b);
	unlimit_rate("vcan1");
	unlimit_rate("vcan2");
}

static int wait_readable(can_port *p, int ms)
{
	struct pollfd pfd = { .fd = can_port_fd(p), .events = POLLIN };
	return poll(&pfd, 1, ms);
}

static void test_open_reports_missing_interface(void)
{
	can_port_config cfg = { .ifname = "nosuchcan9" };
	can_port *p = NULL;
	const char *why = NULL;
	TEST_ASSERT_EQUAL_INT(-ENODEV, can_port_open(&p, &cfg, &why));
	TEST_ASSERT_NULL(p);
	TEST_ASSERT_EQUAL_STRING("no such network interface", why);
	cfg.ifname = "";
	TEST_ASSERT_EQUAL_INT(-EINVAL, can_port_open(&p, &cfg, &why));
}

static void test_frames_round_trip_with_timestamps(void)
{
	co_frame f;
	co_frame_init(&f, 0x181, 8);
	for (int i = 0; i < 8; i++)
		f.data[i] = (uint8_t)(i * 3);
	TEST_ASSERT_EQUAL_INT(0, can_port_send(a, &f, now_us()));
	co_frame e;
	co_frame_init(&e, 0x18FF1234, 2);
	e.flags |= CO_FRAME_EXT;
	e.data[0] = 0xAB;
	TEST_ASSERT_EQUAL_INT(0, can_port_send(a, &e, now_us()));
	co_frame r;
	co_frame_init(&r, 0x705, 1);
	r.flags |= CO_FRAME_RTR;
	TEST_ASSERT_EQUAL_INT(0, can_port_send(a, &r, now_us()));

	can_rx_item items[8];
	int got = 0;
	while (got < 3 && wait_readable(b, 2000) == 1) {
		int n = can_port_recv(b, items + got, 8 - got, now_us());
		TEST_ASSERT_TRUE(n >= 0);
		got += n;
	}
	TEST_ASSERT_EQUAL_INT(3, got);
	TEST_ASSERT_EQUAL_HEX32(0x181, items[0].frame.id);
	TEST_ASSERT_EQUAL_MEMORY(f.data, items[0].frame.data, 8);
	TEST_ASSERT_NOT_EQUAL(0, items[0].kernel_ts_ns);
	TEST_ASSERT_EQUAL_HEX32(0x18FF1234, items[1].frame.id);
	TEST_ASSERT_TRUE(items[1].frame.flags & CO_FRAME_EXT);
	TEST_ASSERT_EQUAL_UINT8(2, items[1].frame.len);
	TEST_ASSERT_TRUE(items[2].frame.flags & CO_FRAME_RTR);
	TEST_ASSERT_EQUAL_UINT8(1, items[2].frame.len);
	TEST_ASSERT_FALSE(items[0].is_error);
	TEST_ASSERT_EQUAL_UINT64(3, can_port_get_stats(a)->tx_frames);
	TEST_ASSERT_EQUAL_UINT64(3, can_port_get_stats(b)->rx_frames);
}

static void test_malformed_frames_are_refused(void)
{
	co_frame f;
	co_frame_init(&f, 0x800, 1); /* 12-bit id without EXT */
	TEST_ASSERT_EQUAL_INT(-EINVAL, can_port_send(a, &f, now_us()));
	co_frame_init(&f, 0x100, 9);
	TEST_ASSERT_EQUAL_INT(-EINVAL, can_port_send(a, &f, now_us()));
	TEST_ASSERT_EQUAL_UINT64(0, can_port_get_stats(a)->tx_frames);
}

/* vcan delivers synchronously, so it never pushes back by itself. A token
 * bucket on the interface makes it behave like a real bus of limited bit rate:
 * frames wait in the qdisc, the socket's send buffer fills, writes fail with
 * EAGAIN/ENOBUFS exactly as on hardware. */
static void limit_rate(const char *ifname, const char *rate)
{
	char cmd[160];
	snprintf(cmd, sizeof cmd,
		 "tc qdisc replace dev %s root tbf rate %s burst 1600 latency 900ms", ifname, rate);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, system(cmd), "tc tbf on a vcan line failed");
}

static void unlimit_rate(const char *ifname)
{
	char cmd[96];
	snprintf(cmd, sizeof cmd, "tc qdisc del dev %s root 2>/dev/null", ifname);
	(void)system(cmd);
}

/* Without reading on the other side, a burst bigger than the kernel takes must
 * end up in our queue (not lost), cross the high watermark, and drain through
 * EPOLLOUT / the retry timer until everything has gone out in order. */
static void test_transmit_back_pressure_drains_in_order(void)
{
	limit_rate("vcan1", "400kbit");
	can_port *sink = open_port("vcan1", 16);
	can_port *src = open_port("vcan1", 3100);
	const int total = 3000;
	int refused = 0;
	for (int i = 0; i < total; i++) {
		co_frame f;
		co_frame_init(&f, 0x200, 2);
		f.data[0] = (uint8_t)i;
		f.data[1] = (uint8_t)(i >> 8);
		if (can_port_send(src, &f, now_us()) != 0)
			refused++;
	}
	TEST_ASSERT_EQUAL_INT(0, refused);
	TEST_ASSERT_TRUE_MESSAGE(can_port_tx_queued(src) > 0,
				 "kernel took the whole burst; no back-pressure seen");
	TEST_ASSERT_EQUAL_INT(1, can_port_take_watermark_event(src));

	int received = 0, wakeups = 0;
	uint64_t deadline = now_us() + 20000000u;
	can_rx_item items[32];
	while (received < total && now_us() < deadline) {
		struct pollfd pfd[2] = { { .fd = can_port_fd(sink), .events = POLLIN },
					 { .fd = can_port_fd(src),
					   .events = can_port_wants_writable(src) ? POLLOUT : 0 } };
		uint64_t retry = can_port_retry_at_us(src);
		int timeout = 100;
		if (retry != UINT64_MAX)
			timeout = retry > now_us() ? (int)((retry - now_us()) / 1000u) + 1 : 0;
		poll(pfd, 2, timeout);
		wakeups++;
		if ((pfd[1].revents & POLLOUT) || (retry != UINT64_MAX && now_us() >= retry))
			can_port_flush(src, now_us());
		int n = can_port_recv(sink, items, 32, now_us());
		for (int i = 0; i < n; i++) {
			int seq = items[i].frame.data[0] | items[i].frame.data[1] << 8;
			TEST_ASSERT_EQUAL_INT_MESSAGE(received, seq, "frame lost or reordered");
			received++;
		}
	}
	TEST_ASSERT_EQUAL_INT(total, received);
	TEST_ASSERT_EQUAL_UINT(0, can_port_tx_queued(src));
	TEST_ASSERT_EQUAL_INT(-1, can_port_take_watermark_event(src));
	/* a busy loop would wake up once per frame or more */
	TEST_ASSERT_TRUE_MESSAGE(wakeups < total, "woke up once per frame or more: busy loop");
	TEST_ASSERT_EQUAL_UINT64(total, can_port_get_stats(src)->tx_frames);
	can_port_close(sink);
	can_port_close(src);
	unlimit_rate("vcan1");
}

static void test_full_queue_refuses_and_counts(void)
{
	limit_rate("vcan2", "100kbit");
	can_port *src = open_port("vcan2", 8);
	int refused = 0;
	for (int i = 0; i < 5000; i++) {
		co_frame f;
		co_frame_init(&f, 0x300, 8);
		if (can_port_send(src, &f, now_us()) == -ENOBUFS)
			refused++;
	}
	TEST_ASSERT_TRUE(refused > 0);
	TEST_ASSERT_EQUAL_UINT64((uint64_t)refused, can_port_get_stats(src)->tx_drops);
	TEST_ASSERT_TRUE(can_port_tx_queued(src) <= 8);
	can_port_close(src);
	unlimit_rate("vcan2");
}

/* A receiver that does not read with a tiny socket buffer: the kernel drops,
 * and the drop count arrives with the next frame we read. */
static void test_receive_overflow_is_counted(void)
{
	int raw = socket(PF_CAN, SOCK_RAW, CAN_RAW);
	TEST_ASSERT_TRUE(raw >= 0);
	struct sockaddr_can addr = { .can_family = AF_CAN,
				     .can_ifindex = (int)if_nametoindex("vcan2") };
	TEST_ASSERT_EQUAL_INT(0, bind(raw, (struct sockaddr *)&addr, sizeof addr));

	can_port_config cfg = { .ifname = "vcan2", .bitrate = 500000, .rcvbuf_bytes = 1 };
	can_port *slow = NULL;
	TEST_ASSERT_EQUAL_INT(0, can_port_open(&slow, &cfg, NULL));
	int small = 1; /* kernel rounds up to its minimum */
	setsockopt(can_port_fd(slow), SOL_SOCKET, SO_RCVBUF, &small, sizeof small);

	struct can_frame k = { .can_id = 0x123, .len = 8 };
	for (int i = 0; i < 2000; i++) {
		if (write(raw, &k, sizeof k) != sizeof k) {
			struct pollfd p = { .fd = raw, .events = POLLOUT };
			poll(&p, 1, 10);
		}
	}
	can_rx_item items[32];
	while (can_port_recv(slow, items, 32, 0) > 0)
		;
	TEST_ASSERT_TRUE(write(raw, &k, sizeof k) == sizeof k);
	TEST_ASSERT_EQUAL_INT(1, wait_readable(slow, 1000));
	while (can_port_recv(slow, items, 32, 0) > 0)
		;
	TEST_ASSERT_TRUE_MESSAGE(can_port_get_stats(slow)->rx_overflow_drops > 0,
				 "no overflow counted");
	can_port_close(slow);
	close(raw);
}

static void test_bus_load_is_estimated(void)
{
	/* 1000 frames of 8 bytes in one second at 500 kbit/s: about 26 % */
	can_port_config cfg = { .ifname = "vcan1", .bitrate = 500000 };
	can_port *p = NULL, *tx = open_port("vcan1", 2048);
	TEST_ASSERT_EQUAL_INT(0, can_port_open(&p, &cfg, NULL));
	uint64_t t0 = now_us();
	int received = 0;
	for (int i = 0; i < 1000; i++) {
		co_frame f;
		co_frame_init(&f, 0x400, 8);
		can_port_send(tx, &f, t0);
		can_port_flush(tx, t0);
		can_rx_item items[32];
		int n = can_port_recv(p, items, 32, t0 + (uint64_t)received * 900u);
		received += n > 0 ? n : 0;
	}
	while (received < 1000 && wait_readable(p, 500) == 1) {
		can_port_flush(tx, t0);
		can_rx_item items[32];
		int n = can_port_recv(p, items, 32, t0 + 900000u);
		received += n > 0 ? n : 0;
	}
	TEST_ASSERT_EQUAL_INT(1000, received);
	/* close the window: the next frame one second later publishes the figure */
	co_frame f;
	co_frame_init(&f, 0x400, 8);
	can_port_send(tx, &f, t0);
	TEST_ASSERT_EQUAL_INT(1, wait_readable(p, 1000));
	can_rx_item items[2];
	can_port_recv(p, items, 2, t0 + 1000000u);
	uint32_t load = can_port_get_stats(p)->bus_load_permille;
	TEST_ASSERT_UINT32_WITHIN(40, 266, load);
	can_port_close(p);
	can_port_close(tx);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_open_reports_missing_interface);
	RUN_TEST(test_frames_round_trip_with_timestamps);
	RUN_TEST(test_malformed_frames_are_refused);
	RUN_TEST(test_transmit_back_pressure_drains_in_order);
	RUN_TEST(test_full_queue_refuses_and_counts);
	RUN_TEST(test_receive_overflow_is_counted);
	RUN_TEST(test_bus_load_is_estimated);
	return UNITY_END();
}
