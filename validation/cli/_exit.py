"""The CLI's exit statuses: one per outcome of the failure policy
(:mod:`pillar_xval.scenes._errors`).

=========================  ==================================================  ====
what happened              reported as                                         exit
=========================  ==================================================  ====
done                                                                           0
solver missed tolerance    ``ContactResult.converged = False``                 1
bad input, or a scene      :class:`~pillar_xval.scenes.InputError`             2
outside a model            (:class:`~pillar_xval.scenes.ScopeError`)
no model for the request   :class:`~pillar_xval.scenes.ScopeError`: ``plan``   2
                           (``--budget`` leaves no candidate, or
                           none can run the scene; the line names
                           the budget and the cheapest candidate's
                           time), ``solve --model auto`` likewise
a tool underneath failed   :class:`~pillar_xval.scenes.ToolError`, memory,     3
                           the file system
an internal error (a bug)  any other exception                                 4
interrupted                Ctrl-C                                              130
terminated                 SIGTERM                                             143
=========================  ==================================================  ====
"""

EXIT_OK = 0
EXIT_NOT_CONVERGED = 1
EXIT_BAD_INPUT = 2
EXIT_TOOL_FAILURE = 3
# An exception that none of the failure policy's kinds covers is a bug of the toolkit: one
# line and this status; --debug, or PILLAR_XVAL_DEBUG set to anything but "" or "0", shows
# its traceback instead.
EXIT_INTERNAL_ERROR = 4
EXIT_INTERRUPTED = 130
# Set to anything but "" or "0": an internal error shows its traceback (as --debug does).
DEBUG_ENV = "PILLAR_XVAL_DEBUG"
EXIT_TERMINATED = 143  # 128 + SIGTERM, as a shell reports a process the signal ended
