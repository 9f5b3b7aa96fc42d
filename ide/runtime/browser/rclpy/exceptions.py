"""rclpy.exceptions (the ones a program catches) for Python in the IDE page."""


class NotInitializedException(Exception):
    def __init__(self, *args):
        Exception.__init__(self, "rclpy.init() has not been called", *args)


class InvalidNameException(Exception):
    pass


class InvalidNodeNameException(InvalidNameException):
    pass


class InvalidNamespaceException(InvalidNameException):
    pass


class InvalidTopicNameException(InvalidNameException):
    pass


class InvalidServiceNameException(InvalidNameException):
    pass


class ParameterException(Exception):
    def __init__(self, error_msg, parameters, *args):
        Exception.__init__(self, "{error_msg}: {parameters}".format(error_msg=error_msg, parameters=parameters))
        self.parameters = parameters


class ParameterNotDeclaredException(ParameterException):
    def __init__(self, parameters, *args):
        ParameterException.__init__(self, "Invalid access to undeclared parameter(s)", parameters, *args)


class ParameterAlreadyDeclaredException(ParameterException):
    def __init__(self, parameters, *args):
        ParameterException.__init__(self, "Parameter(s) already declared", parameters, *args)


class InvalidParameterTypeException(ParameterException):
    def __init__(self, parameter, *args):
        ParameterException.__init__(
            self, "Trying to set parameter '{}' with value {!r} of the wrong type".format(parameter.name, parameter.value),
            parameter, *args)


class ParameterUninitializedException(ParameterException):
    def __init__(self, parameter_name, *args):
        Exception.__init__(self, "The parameter '{}' is not initialized".format(parameter_name))
        self.parameters = parameter_name


class ROSInterruptException(Exception):
    def __init__(self, *args):
        Exception.__init__(self, "rclpy.shutdown() has been called", *args)
