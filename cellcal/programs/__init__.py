"""Robot programs as the controllers read them: find their targets and write them back
compensated, byte for byte elsewhere (URScript: :mod:`.urscript`; KUKA KRL ``.dat``:
:mod:`.krl`; ABB RAPID modules: :mod:`.rapid`). The numbers come from
:mod:`calibration.compensation.pose_compensation` (:mod:`.compensate` joins the two).

Modules
    ``compensate``      compensate a program with a calibration: read, solve, write back,
                        report
    ``program_report``  what compensating a program did, as printed and as JSON
    ``targets``         what a language's reader finds in a program, and the one way it is
                        written back
    ``urscript``        URScript: a program's targets, written back compensated
    ``urscript_exprs``  the URScript expressions a target can be written as
    ``krl``             KUKA KRL ``.dat`` files: the taught points and their rewrite
    ``rapid``           ABB RAPID modules: the targets moved to, their rewrite, and the
                        configuration a robtarget asks for
    ``rapid_data``      RAPID's aggregates and the records a target depends on (robtarget,
                        jointtarget, tooldata, wobjdata, loaddata)
    ``poses``           poses as controller languages write them, to and from 4x4 transforms
    ``tokens``          a small tokenizer for controller languages
"""
