"""--opcua: asyncua's own client finds a station's battery percentage equal to the topic, sees it
change as the robot drives, cannot write it, and signs in with a user name and token under --auth."""

from __future__ import annotations

import asyncio
import re
import threading
import time

import pytest
import roslibpy

from tests.support.ros import client as connect
from tests.support.wait import wait_for

asyncua = pytest.importorskip('asyncua')
from asyncua import Client, ua  # noqa: E402

OPERATOR = 'operator-token-3d4e5f'
ADDRESS = re.compile(r'OPC UA: (opc\.tcp://\S+)')


def opcua_url(gw) -> str:
    m = wait_for(lambda: ADDRESS.search(gw.log_text()), 90, 0.05)   # asyncua builds its address space first
    return m.group(1)


async def child(c: Client, *names: str):
    ns = await c.get_namespace_index('urn:rosgate:twin')
    return await c.nodes.objects.get_child([f'{ns}:Robots', *(f'{ns}:{n}' for n in names)])


async def value_of(url: str, *names: str, user: str | None = None, password: str | None = None) -> float:
    c = Client(url, timeout=10)
    if user:
        c.set_user(user)
        c.set_password(password)
    async with c:
        return await (await child(c, *names)).read_value()


def drive(gw, seconds: float, stop: threading.Event | None = None) -> None:
    with connect(gw) as ros:
        cmd = roslibpy.Topic(ros, '/s01/cmd_vel', 'geometry_msgs/msg/Twist')
        cmd.advertise()
        t0 = time.time()
        while time.time() - t0 < seconds and not (stop and stop.is_set()):
            cmd.publish(roslibpy.Message({'linear': {'x': 0.4, 'y': 0, 'z': 0}, 'angular': {'x': 0, 'y': 0, 'z': 0.6}}))
            time.sleep(0.1)
        cmd.unadvertise()


@pytest.fixture(scope='module')
def twin(start_gateway):
    return start_gateway('--fleet', '1', '--robot', 'rover', '--opcua', '0')


def test_the_battery_percentage_matches_the_topic_changes_as_it_drives_and_is_read_only(twin):
    url = opcua_url(twin)
    seen: list[tuple[float, float]] = []
    with connect(twin) as ros:
        topic = roslibpy.Topic(ros, '/s01/battery_state', 'sensor_msgs/msg/BatteryState')
        topic.subscribe(lambda m: seen.append((time.time(), m['percentage'])))
        wait_for(lambda: len(seen) >= 2, 15, 0.05)
        first = wait_for(lambda: asyncio.run(_maybe(url, 's01', 'battery_state', 'percentage')), 20, 0.2)
        assert abs(first - seen[-1][1]) <= 0.01 * seen[-1][1]          # within 1 % of what the topic says

        drive(twin, 6)
        later = wait_for(lambda: (lambda v: v if v < first - 1e-4 else None)(
            asyncio.run(value_of(url, 's01', 'battery_state', 'percentage'))), 20, 0.2)
        assert abs(later - seen[-1][1]) <= 0.01 * seen[-1][1]
        topic.unsubscribe()

    async def pose_and_write():
        async with Client(url, timeout=10) as c:
            x = await (await child(c, 's01', 'pose', 'x')).read_value()
            yaw = await (await child(c, 's01', 'pose', 'yaw')).read_value()
            node = await child(c, 's01', 'battery_state', 'percentage')
            with pytest.raises(ua.UaStatusCodeError) as refused:
                await node.write_value(ua.DataValue(ua.Variant(0.5, ua.VariantType.Double)))
            after = await node.read_value()
            level = await node.read_attribute(ua.AttributeIds.UserAccessLevel)
            return x, yaw, refused.value, after, level.Value.Value

    x, yaw, refused, after, level = asyncio.run(pose_and_write())
    assert (x, yaw) != (0.0, 0.0)                                       # the rover drove a curve
    assert type(refused).__name__ in ('BadUserAccessDenied', 'BadNotWritable'), refused
    assert after != 0.5 and 0.5 < after <= 1
    assert not level & ua.AccessLevel.CurrentWrite.mask


async def _maybe(url, *names):
    try:
        v = await value_of(url, *names)
    except ua.UaStatusCodeError:   # not there yet: no message taken so far
        return None
    return v if v else None


def test_with_auth_a_user_name_and_its_token_sign_in(start_gateway, tmp_path):
    tokens = tmp_path / 'tokens.toml'
    tokens.write_text(f'[[tokens]]\nname = "alice"\nrole = "operator"\ntoken = "{OPERATOR}"\n')
    gw = start_gateway('--fleet', '1', '--robot', 'rover', '--opcua', '0', '--auth', str(tokens))
    url = opcua_url(gw)
    v = wait_for(lambda: asyncio.run(_signed(url, 'alice', OPERATOR)), 20, 0.2)
    assert 0 < v <= 1
    for user, password in ((None, None), ('alice', 'wrong-token-123456'), ('mallory', OPERATOR)):
        with pytest.raises(Exception) as refused:
            asyncio.run(value_of(url, 's01', 'battery_state', 'percentage', user=user, password=password))
        assert 'Bad' in type(refused.value).__name__ or 'Bad' in str(refused.value), refused.value
    # the token is never sent as given: the plain channel's user name policy encrypts it
    async def policies():
        c = Client(url, timeout=10)
        return await c.connect_and_get_server_endpoints()
    endpoints = asyncio.run(policies())
    plain = [e for e in endpoints if e.SecurityMode == ua.MessageSecurityMode.None_]
    assert plain and all(p.SecurityPolicyUri.endswith('#Basic256Sha256')
                         for e in plain for p in e.UserIdentityTokens if p.TokenType == ua.UserTokenType.UserName)
    assert {p.TokenType for e in endpoints for p in e.UserIdentityTokens} == {ua.UserTokenType.UserName}
    assert any(e.SecurityMode == ua.MessageSecurityMode.SignAndEncrypt for e in endpoints)
    assert gw.alive


async def _signed(url, user, password):
    try:
        return await value_of(url, 's01', 'battery_state', 'percentage', user=user, password=password)
    except ua.UaStatusCodeError as e:
        if 'BadUserAccessDenied' in type(e).__name__:
            raise
        return None
