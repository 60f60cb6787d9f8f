/PROG  TWIN
/ATTR
DEFAULT_GROUP	= 1,*,*,*,*;
/MN
   1:J P[1] 100% FINE ;
   2:L P[2] 100mm/sec FINE ;
   3:J P[3] 100% FINE ;
   4:L P[4] 100mm/sec FINE ;
   5:J P[5] 100% FINE ;
   6:L P[6] 100mm/sec FINE ;
/POS
P[1]{
   GP1:
	UF : 1, UT : 1,
	J1=-21.136 deg,	J2=-19.188 deg,	J3=21.324 deg,
	J4=-35.080 deg,	J5=-74.434 deg,	J6=106.862 deg
};
P[2]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =95.883  mm,	Y =108.262  mm,	Z =1583.451  mm,
	W =29.849 deg,	P =35.905 deg,	R =74.122 deg
};
P[3]{
   GP1:
	UF : 1, UT : 1,
	J1=-21.522 deg,	J2=-27.514 deg,	J3=12.984 deg,
	J4=-162.725 deg,	J5=-56.327 deg,	J6=1.095 deg
};
P[4]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =15.016  mm,	Y =-18.033  mm,	Z =1175.882  mm,
	W =33.190 deg,	P =-127.498 deg,	R =113.084 deg
};
P[5]{
   GP1:
	UF : 1, UT : 1,
	J1=-0.782 deg,	J2=-12.553 deg,	J3=-24.513 deg,
	J4=-49.836 deg,	J5=23.135 deg,	J6=-91.687 deg
};
P[6]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'F U T, 0, 0, 0',
	X =132.835  mm,	Y =35.732  mm,	Z =1973.773  mm,
	W =123.077 deg,	P =-147.719 deg,	R =22.780 deg
};
/END
