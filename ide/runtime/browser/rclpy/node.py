"""rclpy.node.Node (Jazzy's API) for Python in the IDE page.

A node's names resolve as ROS resolves them: relative names in the node's namespace, ``~`` in the
node's own. The node's namespace is the page's robot namespace when it has one (as
``ros2 run ... --ros-args -r __ns:=/s07`` sets it on a robot), else the one the program gives.
Parameters live in the node (the page's node serves no parameter services to the graph); the
graph queries ask the gateway (rosapi).
"""

import os
import re

from rclpy import _engine
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.client import Client
from rclpy.clock import Clock, ROSClock
from rclpy.context import default_context
from rclpy.exceptions import (InvalidNodeNameException, InvalidTopicNameException, NotInitializedException,
                              ParameterAlreadyDeclaredException, ParameterNotDeclaredException,
                              ParameterUninitializedException)
from rclpy.logging import get_logger
from rclpy.parameter import Parameter, SetParametersResult
from rclpy.publisher import Publisher
from rclpy.qos import profile, qos_profile_services_default
from rclpy.service import Service
from rclpy.subscription import Subscription
from rclpy.timer import Rate, Timer

NODE_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
TOPIC_NAME = re.compile(r"^[~/A-Za-z_{][A-Za-z0-9_/{}~]*$")


def _namespace(given):
    robot = os.environ.get("ROSGATE_NS", "")
    ns = robot or given or "/"
    ns = "/" + ns.strip("/")
    return ns


class Node:
    PARAM_REL_TOL = 1e-6

    def __init__(self, node_name, *, context=None, cli_args=None, namespace=None, use_global_arguments=True,
                 enable_rosout=True, start_parameter_services=True, parameter_overrides=None,
                 allow_undeclared_parameters=False, automatically_declare_parameters_from_overrides=False,
                 enable_logger_service=False):
        self._context = default_context() if context is None else context
        if not self._context.ok():
            raise NotInitializedException("cannot create node")
        if not NODE_NAME.match(str(node_name)):
            raise InvalidNodeNameException(
                "node name {!r} is invalid: it must start with a letter or '_' and hold only letters, digits "
                "and '_'".format(node_name))
        self._name = node_name
        self._ns = _namespace(namespace)
        self._timers, self._subscriptions, self._publishers = [], [], []
        self._services, self._clients, self._action_servers, self._action_clients = [], [], [], []
        self._default_callback_group = MutuallyExclusiveCallbackGroup()
        self._executor = None
        self._clock = ROSClock()
        self._logger = get_logger(self.get_fully_qualified_name().lstrip("/").replace("/", "."))
        self._parameters = {}
        self._descriptors = {}
        self._overrides = {p.name: p for p in parameter_overrides or []}
        self._allow_undeclared = allow_undeclared_parameters
        self._set_callbacks = []
        if automatically_declare_parameters_from_overrides:
            for p in self._overrides.values():
                self._parameters[p.name] = p
        _engine.engine()

    # ---- who
    def get_name(self):
        return self._name

    def get_namespace(self):
        return self._ns

    def get_fully_qualified_name(self):
        return (self._ns.rstrip("/") + "/" + self._name) if self._ns != "/" else "/" + self._name

    def get_logger(self):
        return self._logger

    def get_clock(self):
        return self._clock

    @property
    def context(self):
        return self._context

    @property
    def handle(self):
        return self

    @property
    def default_callback_group(self):
        return self._default_callback_group

    @property
    def executor(self):
        return self._executor

    @executor.setter
    def executor(self, new_executor):
        if self._executor is not None and self._executor is not new_executor:
            self._executor.remove_node(self)
        self._executor = new_executor
        if new_executor is not None:
            new_executor.add_node(self)

    publishers = property(lambda self: iter(self._publishers))
    subscriptions = property(lambda self: iter(self._subscriptions))
    clients = property(lambda self: iter(self._clients))
    services = property(lambda self: iter(self._services))
    timers = property(lambda self: iter(self._timers))

    # ---- names
    def resolve_name(self, name, only_expand=False):
        """A topic, service or action name as the graph knows it (absolute)."""
        name = str(name)
        if not name or not TOPIC_NAME.match(name) or "//" in name or (name.endswith("/") and name != "/"):
            raise InvalidTopicNameException("topic name {!r} is invalid".format(name))
        name = name.replace("{node}", self._name).replace("{ns}", self._ns).replace("{namespace}", self._ns)
        if name.startswith("~"):
            return self.get_fully_qualified_name() + name[1:]
        if name.startswith("/"):
            return name
        return (self._ns.rstrip("/") + "/" + name) if self._ns != "/" else "/" + name

    resolve_topic_name = resolve_name
    resolve_service_name = resolve_name

    # ---- entities
    def create_publisher(self, msg_type, topic, qos_profile, *, callback_group=None, event_callbacks=None,
                         qos_overriding_options=None, publisher_class=Publisher):
        pub = publisher_class(self, msg_type, self.resolve_name(topic), profile(qos_profile),
                              callback_group or self._default_callback_group)
        self._publishers.append(pub)
        return pub

    def create_subscription(self, msg_type, topic, callback, qos_profile, *, callback_group=None,
                            event_callbacks=None, qos_overriding_options=None, raw=False):
        group = callback_group or self._default_callback_group
        sub = Subscription(self, msg_type, self.resolve_name(topic), callback, group, profile(qos_profile), raw)
        group.add_entity(sub)
        self._subscriptions.append(sub)
        return sub

    def create_client(self, srv_type, srv_name, *, qos_profile=qos_profile_services_default, callback_group=None):
        group = callback_group or self._default_callback_group
        client = Client(self, srv_type, self.resolve_name(srv_name), qos_profile, group)
        group.add_entity(client)
        self._clients.append(client)
        return client

    def create_service(self, srv_type, srv_name, callback, *, qos_profile=qos_profile_services_default,
                       callback_group=None):
        group = callback_group or self._default_callback_group
        service = Service(self, srv_type, self.resolve_name(srv_name), callback, group, qos_profile)
        group.add_entity(service)
        self._services.append(service)
        return service

    def create_timer(self, timer_period_sec, callback, callback_group=None, clock=None, autostart=True):
        group = callback_group or self._default_callback_group
        timer = Timer(callback, group, float(timer_period_sec) * 1e9, clock or self._clock,
                      context=self._context, autostart=autostart)
        group.add_entity(timer)
        self._timers.append(timer)
        return timer

    def create_rate(self, frequency, clock=None):
        if frequency <= 0:
            raise ValueError("frequency must be > 0")
        return Rate(frequency)

    def _destroy(self, entity, entities):
        if entity in entities:
            entities.remove(entity)
            entity.destroy()
            return True
        return False

    def destroy_publisher(self, publisher):
        return self._destroy(publisher, self._publishers)

    def destroy_subscription(self, subscription):
        return self._destroy(subscription, self._subscriptions)

    def destroy_client(self, client):
        return self._destroy(client, self._clients)

    def destroy_service(self, service):
        return self._destroy(service, self._services)

    def destroy_timer(self, timer):
        return self._destroy(timer, self._timers)

    def destroy_rate(self, rate):
        return True

    def destroy_node(self):
        for entities in (self._publishers, self._subscriptions, self._clients, self._services, self._timers):
            for entity in list(entities):
                self._destroy(entity, entities)
        for server in list(self._action_servers):
            server.destroy()
        for client in list(self._action_clients):
            client.destroy()
        if self._executor is not None:
            self._executor.remove_node(self)
            self._executor = None

    # ---- the graph (through the gateway's rosapi)
    def get_topic_names_and_types(self, no_demangle=False):
        r = _engine.Engine.rosapi("topics")
        return sorted((n, [t]) for n, t in zip(r.get("topics") or [], r.get("types") or []))

    def get_service_names_and_types(self):
        out = []
        for name in _engine.Engine.rosapi("services").get("services") or []:
            t = _engine.Engine.rosapi("service_type", {"service": name}).get("type")
            out.append((name, [t] if t else []))
        return sorted(out)

    def get_node_names(self):
        return [n.rsplit("/", 1)[-1] for n in _engine.Engine.rosapi("nodes").get("nodes") or []]

    def get_node_names_and_namespaces(self):
        out = []
        for n in _engine.Engine.rosapi("nodes").get("nodes") or []:
            ns, _, name = n.rpartition("/")
            out.append((name, ns or "/"))
        return out

    def count_publishers(self, topic_name):
        return len(_engine.Engine.rosapi("publishers", {"topic": self.resolve_name(topic_name)}).get("publishers") or [])

    def count_subscribers(self, topic_name):
        return len(_engine.Engine.rosapi("subscribers", {"topic": self.resolve_name(topic_name)}).get("subscribers") or [])

    # ---- parameters
    def declare_parameter(self, name, value=None, descriptor=None, ignore_override=False):
        if name in self._parameters:
            raise ParameterAlreadyDeclaredException([name])
        if name in self._overrides and not ignore_override:
            parameter = Parameter(name, value=self._overrides[name].value)
        elif isinstance(value, Parameter.Type):
            parameter = Parameter(name, Parameter.Type.NOT_SET, None)
            self._descriptors[name] = value
        else:
            parameter = Parameter(name, value=value)
        result = self._set_checked([parameter], declaring=True)[0]
        if not result.successful:
            raise ValueError("cannot declare parameter {}: {}".format(name, result.reason))
        self._parameters[name] = parameter
        if parameter.type_ != Parameter.Type.NOT_SET:
            self._descriptors.setdefault(name, parameter.type_)
        return parameter

    def declare_parameters(self, namespace, parameters, ignore_override=False):
        out = []
        for item in parameters:
            name = item[0] if isinstance(item, tuple) else item
            value = item[1] if isinstance(item, tuple) and len(item) > 1 else None
            full = "{}.{}".format(namespace, name) if namespace else name
            out.append(self.declare_parameter(full, value, ignore_override=ignore_override))
        return out

    def undeclare_parameter(self, name):
        if name not in self._parameters:
            raise ParameterNotDeclaredException([name])
        del self._parameters[name]
        self._descriptors.pop(name, None)

    def has_parameter(self, name):
        return name in self._parameters

    def get_parameter(self, name):
        if name in self._parameters:
            parameter = self._parameters[name]
            if parameter.type_ == Parameter.Type.NOT_SET and name in self._descriptors:
                raise ParameterUninitializedException(name)
            return parameter
        if self._allow_undeclared:
            return Parameter(name, Parameter.Type.NOT_SET, None)
        raise ParameterNotDeclaredException([name])

    def get_parameter_or(self, name, alternative_value=None):
        if alternative_value is None:
            alternative_value = Parameter(name, Parameter.Type.NOT_SET)
        return self._parameters.get(name, alternative_value)

    def get_parameters(self, names):
        return [self.get_parameter(n) for n in names]

    def get_parameters_by_prefix(self, prefix):
        prefix = prefix + "." if prefix else ""
        return {n[len(prefix):]: p for n, p in self._parameters.items() if n.startswith(prefix)}

    def set_parameters(self, parameter_list):
        out = []
        for parameter in parameter_list:
            if parameter.name not in self._parameters and not self._allow_undeclared:
                raise ParameterNotDeclaredException([parameter.name])
            result = self._set_checked([parameter])[0]
            if result.successful:
                self._parameters[parameter.name] = parameter
            out.append(result)
        return out

    def set_parameters_atomically(self, parameter_list):
        results = [self._set_checked([p])[0] for p in parameter_list]
        if all(r.successful for r in results):
            for p in parameter_list:
                self._parameters[p.name] = p
            return SetParametersResult(successful=True)
        return next(r for r in results if not r.successful)

    def _set_checked(self, parameters, declaring=False):
        results = []
        for parameter in parameters:
            expected = self._descriptors.get(parameter.name)
            if (not declaring and expected is not None and parameter.type_ != expected
                    and parameter.type_ != Parameter.Type.NOT_SET):
                results.append(SetParametersResult(successful=False, reason="Wrong parameter type, expected '{}' got '{}'"
                                                   .format(expected, parameter.type_)))
                continue
            result = SetParametersResult(successful=True)
            for callback in self._set_callbacks:
                result = callback([parameter])
                if not result.successful:
                    break
            results.append(result)
        return results

    def add_on_set_parameters_callback(self, callback):
        self._set_callbacks.insert(0, callback)

    def remove_on_set_parameters_callback(self, callback):
        self._set_callbacks.remove(callback)

    def describe_parameter(self, name):
        return self._descriptors.get(name)

    def __repr__(self):
        return "<rclpy.node.Node %s>" % self.get_fully_qualified_name()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.destroy_node()
        return False


__all__ = ["Node", "Clock"]
