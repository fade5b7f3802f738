MODULE CellcalServer
    !
    ! cellcal's RAPID server module: moves the robot to the targets cellcal's ABB driver
    ! (drivers/abb/driver.py) writes through Robot Web Services, one at a time.
    !
    ! Load it as the main module of the motion task T_ROB1 (PROC main below), AUTO mode,
    ! motors on, then start RAPID (the driver restarts it from main when it finds it
    ! stopped). docs/abb.md describes the protocol:
    !
    !   the driver writes the target (cc_joints and cc_time, or cc_xyz and cc_speed), the
    !   zone (cc_zone) and the kind (cc_kind), and last a new request number (cc_seq);
    !   this module sees cc_seq <> cc_ack, checks the target, moves (busy: cc_busy = 1,
    !   zone fine: the instruction ends in position), and acknowledges: cc_err and cc_msg
    !   say how it ended, then cc_ack := cc_seq.
    !
    ! A target outside the joint limits (read from the MOC configuration at start) or out of
    ! reach moves nothing: cc_err 1 (LIMIT) or 2 (UNREACHABLE). Any other RAPID error stops
    ! the task with the error in the event log, which the driver reads.
    !
    PERS num cc_seq := 0;
    PERS num cc_ack := 0;
    PERS num cc_busy := 0;
    PERS num cc_kind := 0;
    PERS jointtarget cc_joints := [[0,0,0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    PERS num cc_time := 1;
    PERS pos cc_xyz := [0,0,0];
    PERS speeddata cc_speed := [100,500,5000,1000];
    PERS zonedata cc_zone := [TRUE,0,0,0,0,0,0];
    PERS string cc_toolname := "tool0";
    PERS num cc_err := 0;
    PERS string cc_msg := "";

    VAR num cc_lower{6};
    VAR num cc_upper{6};
    VAR tooldata cc_tool;

    PROC main()
        ReadLimits;
        cc_busy := 0;
        ! a restart from main forgets a request it did not serve
        cc_ack := cc_seq;
        WHILE TRUE DO
            WaitUntil cc_seq <> cc_ack \PollRate:=0.01;
            Serve;
        ENDWHILE
    ENDPROC

    PROC ReadLimits()
        ! the joint bounds of the MOC configuration (radians), per axis of the arm
        VAR string arm;
        VAR num value;
        FOR i FROM 1 TO 6 DO
            arm := "/MOC/ARM/rob1_" + NumToStr(i, 0);
            ReadCfgData arm, "lower_joint_bound", value;
            cc_lower{i} := value * 180 / pi;
            ReadCfgData arm, "upper_joint_bound", value;
            cc_upper{i} := value * 180 / pi;
        ENDFOR
    ENDPROC

    FUNC bool OutsideLimits(jointtarget target)
        VAR num j{6};
        j := [target.robax.rax_1, target.robax.rax_2, target.robax.rax_3,
              target.robax.rax_4, target.robax.rax_5, target.robax.rax_6];
        FOR i FROM 1 TO 6 DO
            IF j{i} < cc_lower{i} OR j{i} > cc_upper{i} THEN
                cc_msg := "LIMIT: joint " + NumToStr(i, 0) + " outside its bounds";
                RETURN TRUE;
            ENDIF
        ENDFOR
        RETURN FALSE;
    ENDFUNC

    PROC Serve()
        VAR num seq;
        VAR robtarget here;
        VAR jointtarget check;
        seq := cc_seq;
        cc_err := 0;
        cc_msg := "";
        GetDataVal cc_toolname, cc_tool;
        IF cc_kind = 1 THEN
            IF OutsideLimits(cc_joints) THEN
                cc_err := 1;
            ELSE
                cc_busy := 1;
                MoveAbsJ cc_joints \NoEOffs, v1000 \T:=cc_time, cc_zone, cc_tool;
            ENDIF
        ELSEIF cc_kind = 2 THEN
            here := CRobT(\Tool:=cc_tool \WObj:=wobj0);
            here.trans := cc_xyz;
            ! ERR_ROBLIMIT (handled below) when the target is out of reach
            check := CalcJointT(here, cc_tool \WObj:=wobj0);
            IF OutsideLimits(check) THEN
                cc_err := 1;
            ELSE
                cc_busy := 1;
                MoveL here, cc_speed, cc_zone, cc_tool \WObj:=wobj0;
            ENDIF
        ELSE
            cc_err := 3;
            cc_msg := "BAD_ARGUMENT: cc_kind must be 1 (MoveAbsJ) or 2 (MoveL)";
        ENDIF
        cc_busy := 0;
        cc_ack := seq;
    ERROR
        IF ERRNO = ERR_ROBLIMIT OR ERRNO = ERR_OUTSIDE_REACH THEN
            cc_err := 2;
            cc_msg := "UNREACHABLE: ERR_ROBLIMIT, the target is out of reach";
            cc_busy := 0;
            cc_ack := seq;
            RETURN;
        ENDIF
        ! anything else stops the task: the event log says why
        RAISE;
    ENDPROC
ENDMODULE
