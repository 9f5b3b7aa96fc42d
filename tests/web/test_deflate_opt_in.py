"""?compression=deflate on the websocket URL: permessage-deflate for that connection alone (the
class view asks for it); other connections stay uncompressed (their CPU is the class's)."""

from __future__ import annotations

from websockets.sync.client import connect


def extensions(url: str) -> list[str]:
    with connect(url, compression='deflate', open_timeout=10) as ws:
        ws.send('{"op": "call_service", "id": "a", "service": "/rosapi/get_time"}')
        assert '"service_response"' in ws.recv(timeout=5)   # frames flow both ways, compressed or not
        return [type(e).__name__ for e in ws.protocol.extensions]


def test_deflate_only_when_asked(gateway):
    assert extensions(gateway.ws_url) == []
    assert extensions(gateway.ws_url + '?compression=deflate') == ['PerMessageDeflate']
    assert extensions(gateway.ws_url + '?name=teacher&compression=deflate') == ['PerMessageDeflate']
