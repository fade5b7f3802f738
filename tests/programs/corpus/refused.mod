MODULE Refused(NOSTEPIN)
  ! what cannot be compensated, and why
  PERS tooldata tFixed:=[FALSE,[[500,0,400],[1,0,0,0]],[1,[0,0,0],[1,0,0,0],0,0,0]];
  PERS tooldata tGrip:=[TRUE,[[0,0,150],[1,0,0,0]],[2,[0,0,60],[1,0,0,0],0,0,0]];
  PERS wobjdata wConveyor:=[FALSE,FALSE,"CNV1",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
  CONST robtarget pA:=[[1000,0,1200],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget pB:=[[1000,200,1200],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget pBad:=[[1000,200,1200],[1,1,1,1],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  VAR robtarget pSeen;
  CONST robtarget pTrack:=[[1000,-200,1200],[0,0,1,0],[-1,0,-1,0],[1500,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget pSpare:=[[900,0,1100],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];

  PROC main()
    MoveL pA, v100, fine, tGrip;
    MoveL Offs(pA, 0, 0, 100), v100, fine, tGrip;
    pSeen := CRobT(\Tool:=tGrip);
    MoveL pSeen, v100, fine, tGrip;
    MoveL pB, v100, fine, tFixed;
    MoveL pB, v100, fine, tGrip\WObj:=wConveyor;
    MoveL pA, v100, fine, tool0;
    MoveJ pBad, v100, fine, tGrip;
    MoveL pB, v100, fine, tOther;
    GripLoad load0;
    PDispOn \ExeP:=pA, pA, tGrip;
    MoveL pTrack, v100, fine, tGrip;
    approach [[1000,0,1300],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    ArcL [[1000,0,1300],[0,0,1,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]], v100, seam1, weld1, fine, tGrip;
  ENDPROC

  PROC approach(robtarget pTo)
    MoveJ pTo, v500, z10, tGrip;
  ENDPROC
ENDMODULE
