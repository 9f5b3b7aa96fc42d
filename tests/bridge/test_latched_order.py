"""A latched topic's retained message never reaches a subscriber after a newer live one, even
when the live one is published in the same breath as the subscribe."""

from __future__ import annotations

import pytest

from tests.support.rawclient import Raw

TOPIC = '/order/latched'
STRING = 'std_msgs/msg/String'


def received(client: Raw, topic: str) -> list[int]:
    """A round trip, then the numbers published on topic that arrived before its answer."""
    client.seen.clear()
    client.sync()
    return [int(m['msg']['data']) for m in client.seen if m.get('op') == 'publish' and m.get('topic') == topic]


@pytest.mark.parametrize('shared', [False, True], ids=['first-subscriber', 'joins-a-shared-subscription'])
def test_retained_message_comes_before_the_live_one_published_with_the_subscribe(gateway, shared):
    topic = f'{TOPIC}/{"shared" if shared else "alone"}'
    with Raw(gateway.ws_url) as client, Raw(gateway.ws_url) as watcher:
        client.send({'op': 'advertise', 'topic': topic, 'type': STRING, 'latch': True, 'queue_size': 1})
        client.send({'op': 'publish', 'topic': topic, 'msg': {'data': '0'}})
        client.sync()
        if shared:   # another client holds the topic's one backend subscription throughout
            watcher.send({'op': 'subscribe', 'topic': topic, 'type': STRING})
            assert received(watcher, topic) == [0]
        for n in range(1, 41):
            client.send_together({'op': 'subscribe', 'topic': topic, 'type': STRING},
                                 {'op': 'publish', 'topic': topic, 'msg': {'data': str(n)}})
            assert received(client, topic) == [n - 1, n], f'round {n}'
            client.send({'op': 'unsubscribe', 'topic': topic})
        if shared:
            assert received(watcher, topic) == list(range(1, 41))
