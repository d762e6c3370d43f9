"""The plan of any launch: independent houses or a community of houses sharing one H2 hub.

:func:`plan_any` is what the launcher, ``launch --print-plan`` and the ROS 2 launch file
call: a community (``LaunchOptions.community``) is planned by
:func:`comems4build_ros.run.community.plan_community`, which builds on the node plans of
:mod:`comems4build_ros.run.plan`; every other run by :func:`comems4build_ros.run.plan.plan_run`.
(The two modules stay apart so that neither imports the other in a circle.)
"""

from __future__ import annotations

from typing import Any

from comems4build_ros.run.community import plan_community
from comems4build_ros.run.plan import LaunchOptions, RunPlan, plan_run


def plan_any(opts: LaunchOptions, domain_id: int, params: Any = None) -> RunPlan:
    """Return the plan of ``opts`` on ``domain_id``; starts nothing.

    Parameters
    ----------
    opts : launch options
    domain_id : ROS domain id of the run
    params : checked plant parameters (default ``opts.params``, else loaded from
        ``opts.config_files`` and ``opts.overrides``)

    Raises
    ------
    ValueError, ConfigError
        For options the run cannot take (see :func:`~comems4build_ros.run.plan.plan_run` and
        :func:`~comems4build_ros.run.community.plan_community`).
    """
    if opts.community is None:
        return plan_run(opts, domain_id, params)
    from comems4build_ros.core.config import load_plant_params

    return plan_community(opts, domain_id, params or opts.params or load_plant_params(opts.config_files,
                                                                                      opts.overrides))
