"""A community of houses sharing one hydrogen hub (``docs/community.md``).

The community composes the house of the paper, it does not copy it: every house is an
unchanged :class:`~comems4build_ros.core.plant.Plant` with its own EMS of
:mod:`comems4build_ros.core.ems`; what is added is

- :mod:`.spec`: the community file (the houses and how they differ, the hub's size);
- :mod:`.hub`: the shared electrolyser modules and H2 store, with one H2 account per house;
- :mod:`.plant`: the community plant, the houses' plants and the hub in one step, and the
  electricity balance at the connection point;
- :mod:`.sharing`: the rules for electricity shared inside the community, as data;
- :mod:`.coordinator`: what a coordinator reads and decides, and the table of coordinators
  (``config/coordinators.yaml``); :mod:`.rule`: the rule-based coordinator;
- :mod:`.loop`: the in-process community run; :mod:`.kpi`: the community's KPIs.
"""
