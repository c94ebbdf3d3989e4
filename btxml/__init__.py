"""BehaviorTree.CPP XML in and out: ``homing import`` (BT.CPP v3/v4 and Nav2 trees → missions) and ``homing export``.

Not the mission language itself (that is :mod:`homing.missions`): a bridge
to the format Nav2's navigators, Groot2 and BT.CPP applications use.
:mod:`~homing.btxml.reader` reads XML safely with positions,
:mod:`~homing.btxml.catalog` says which homing node each BT.CPP and Nav2
node becomes, :mod:`~homing.btxml.importer` and
:mod:`~homing.btxml.exporter` convert.
"""
