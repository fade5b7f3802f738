MODULE AbbCell
  ! An IRB 2600-12/1.65 picks a part off a table and traces a seam.
  ! tSmr: the tracker's SMR in a nest on the flange, the point the calibration measured.
  PERS tooldata tSmr:=[TRUE,[[0,0,0],[1,0,0,0]],[0.5,[0,0,20],[1,0,0,0],0,0,0]];
  TASK PERS wobjdata wTable:=[FALSE,TRUE,"",[[600,-400,150],[0.9659258,0,0,0.258819]],
                              [[0,0,0],[1,0,0,0]]];
  CONST jointtarget jHome:=[[0,0,0,0,30,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget pApproach:=[[1119.56,120.86,1194.63],[0.2668316,-0.1934934,0.9427167,0.0514432],[0,0,-1,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  PERS robtarget pGrip:=[[311.42,-532.47,499.07],[0.0053485,-0.605577,-0.7795554,0.1598163],[-1,-1,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget seam{3}:=[
    [[1068.71,401.62,882.52],[0.031326,-0.0739232,0.9954425,0.0514618],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],
    [[1054.17,534.97,873.4],[0.0388979,-0.1339008,0.9869072,0.0810666],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],
    [[1027.74,674.68,844.64],[0.0336159,-0.1883392,0.974714,0.1154593],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]];

  PROC main()
    MoveAbsJ jHome, v1000, z50, tSmr;
    MoveJ pApproach, v1000, z50, tSmr;
    MoveL pGrip, v200, fine, tSmr\WObj:=wTable;
    FOR i FROM 1 TO 3 DO
      MoveL seam{i}, v100, z1, tSmr;
    ENDFOR
    MoveC [[1285.36,0,984.63],[0.1305262,0,0.9914449,0],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],
          [[1294.44,238.01,996.57],[0.128472,-0.1144406,0.9842304,0.0410951],[0,0,-1,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],
          v100, fine, tSmr;
    MoveAbsJ jHome, v1000, z50, tSmr;
  ENDPROC
ENDMODULE
